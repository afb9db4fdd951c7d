"""MuJoCo simulation of press-and-release palpation: a stream source for palpate.core.

``import palpate.sim`` stays cheap: MuJoCo and trimesh are imported only when a press runs. One press:
``simulate_press``; many at once, each equal to the same press alone: ``simulate_presses`` (:mod:`.batch`).
"""

from palpate.sim.api import simulate_press
from palpate.sim.batch import PressSpec, simulate_presses

__all__ = ["PressSpec", "simulate_press", "simulate_presses"]
