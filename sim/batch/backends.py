"""Where the physics of a batch of presses runs: backends by name.

A backend is a function ``fn(jobs) -> traces``: a sequence of :class:`~palpate.sim.batch.analytic.AnalyticJob`
in, one :class:`~palpate.sim.trace.PhysicsTrace` per job out, in order, equal to what
:func:`palpate.sim.analytic.run_analytic_press` gives for each. ``cpu`` (numpy, :mod:`.analytic`) is palpate's own
and the default. A GPU backend (e.g. one on MuJoCo Warp, shipped behind its own extra) plugs in with
:func:`register_backend` in process, or as an entry point of group ``palpate.sim_backends`` of another
distribution: nothing in palpate imports it unless it is named.
"""

from __future__ import annotations

from palpate.core.plugins import SIM_BACKENDS, register, resolve, unregister
from palpate.sim.batch.analytic import cpu_analytic_traces

#: The backend a batch uses unless told otherwise.
DEFAULT_BACKEND = "cpu"


def register_backend(name: str, fn, replace: bool = False) -> None:
    """Register the batch physics ``fn(jobs) -> traces`` under ``name`` for this process (``replace``: over an
    earlier registration). ValidationError for palpate's own name ``cpu`` or a name already taken."""
    register(SIM_BACKENDS, name, fn, replace=replace)


def unregister_backend(name: str) -> None:
    """Remove an in-process backend (nothing happens when there is none)."""
    unregister(SIM_BACKENDS, name)


def resolve_backend(name: str):
    """The physics function of backend ``name``; ValidationError naming the known backends for an unknown one."""
    plugin = resolve(SIM_BACKENDS, name)
    return cpu_analytic_traces if plugin.obj is None else plugin.obj
