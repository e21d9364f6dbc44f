"""Emulated dome drivers: the real drivers' behaviour on one machine (``dome_emulator``)."""
