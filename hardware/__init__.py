"""Real devices (Tekscan, Polhemus Liberty, Dynamixel finger) and their wire-protocol emulators."""
