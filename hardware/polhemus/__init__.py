"""Polhemus Liberty motion tracker: binary/ASCII protocol driver and a pty emulator."""
