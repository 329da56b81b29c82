"""Results on disk and on screen: trial logs (thesis CSV, TUM, sidecars), the results folder, text and Markdown
tables, figures and videos, and the provenance (version, commit, machine) every results folder records."""
