"""The virtual DSP: the one place where the emulator meets firmware_model's firmware."""
