"""Example psns-hil plugin package (docs/plugins.md): ``firmware.filter: scaled_q`` and ``logfile://NAME`` URLs."""
