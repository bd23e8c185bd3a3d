"""Recording: captures, the change indicator (goldens), reports and replay."""
