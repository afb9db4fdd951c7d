"""MuJoCo simulation of press-and-release palpation: a stream source for palpate.core.

``import palpate.sim`` stays cheap: MuJoCo and trimesh are imported only when a press runs.
"""

from palpate.sim.api import simulate_press

__all__ = ["simulate_press"]
