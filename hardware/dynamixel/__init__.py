"""Dynamixel (Protocol 2.0) robotic finger through dynamixel-sdk, and a pty servo emulator."""
