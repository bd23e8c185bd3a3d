"""Truth models: trajectory (and, later, Sun and sky)."""
