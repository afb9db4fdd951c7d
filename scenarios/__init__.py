"""palpate.scenarios: the scenario files shipped with palpate (``palpate scenarios list``). No code: found with
importlib.resources (see palpate.core.world.resources)."""
