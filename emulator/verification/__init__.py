"""Verification: the scenario's expectations, evaluated at the end of a run."""
