"""Tekscan tactile arrays: import of the ASCII/CSV movie export (the live API is Windows-only)."""
