"""Boundaries inside a press: where a wall between two materials lies, read from the taxel image."""
