"""Batched simulated presses: N presses at once, each equal to the same press made alone.

- :func:`simulate_presses` — N :class:`PressSpec` (simulate_press's arguments) -> N PressRecording.
- :func:`press_batch` — N targets on one :class:`~palpate.sim.source.SimSource` -> N PressRecording (also
  ``SimSource.press_many``).
- :func:`press_across` — presses of several sources (vector environments, sweep variants) in one batch.
- :func:`register_backend` — where the batch physics runs: ``cpu`` (numpy) by default; a GPU backend plugs in here
  (:mod:`.backends`).

The analytic rung is batched (every press's sensel pressures in one vectorised integration); presses of the other
rungs run one at a time inside the same call.
"""

from palpate.sim.batch.backends import DEFAULT_BACKEND, register_backend, resolve_backend, unregister_backend
from palpate.sim.batch.press import press_across, press_batch
from palpate.sim.batch.specs import PressSpec, simulate_presses

__all__ = ["DEFAULT_BACKEND", "PressSpec", "press_across", "press_batch", "register_backend", "resolve_backend",
           "simulate_presses", "unregister_backend"]
