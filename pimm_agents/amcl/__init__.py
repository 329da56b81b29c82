"""AMCL as nav2_amcl runs it: the likelihood-field scan model and the filter."""
