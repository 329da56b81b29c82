"""Localizers that consume the env's observations and report a pose (PIMM's particle filter, AMCL).

Empty until the localizer issues land; see ``../shared/ARCHITECTURE.md`` for the contract.
"""
