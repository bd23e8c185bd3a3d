"""Assembly: a scenario turned into links, devices, world and firmware, and the run session."""
