"""The commands of ``evaluate.py``, by what they do: measure, bags, worlds."""
