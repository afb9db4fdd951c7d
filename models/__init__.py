"""palpate.models: data shipped with palpate (finger descriptions, calibration tables, haptic-material maps).
No code: found with importlib.resources (see palpate.core.world.resources)."""
