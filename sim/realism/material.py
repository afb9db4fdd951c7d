"""What real foams and rubbers add to an elastic contact: relaxation under load, softening over repeated presses.

Relaxation is a standard linear solid (one Prony term) applied to the elastic force history the physics computed:

    F(t) = (1 - g) F_el(t) + g integral_0^t exp(-(t - s) / tau) dF_el(s),

so a fast press feels stiffer than a slow one (rate dependence), the force falls during a hold, and on release the
material lags behind the finger (the force can reach zero before the finger leaves: clipped, a foam does not pull).
The pressure over each sensel follows the force in proportion (the patch is the elastic one). Softening scales
the material's stiffness by :meth:`~palpate.sim.realism.profile.MaterialRealism.softening_factor` of the number of
earlier presses at the same spot (the press is planned with the softened law, so a force-limited press goes deeper).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from palpate.sim.realism.profile import MaterialRealism
from palpate.sim.trace import PhysicsTrace


def relax_force(t: np.ndarray, elastic: np.ndarray, relaxation: float, tau: float) -> np.ndarray:
    """The viscoelastic force, N, of an elastic force history ``elastic`` (N) sampled at times ``t`` (s).

    Exact for a force that is linear between samples (the convolution is integrated piece by piece).
    """
    f = np.asarray(elastic, dtype=float)
    if relaxation <= 0 or len(f) < 2:
        return f.copy()
    dt = np.diff(np.asarray(t, dtype=float))
    decay = np.exp(-dt / tau)
    # the response to a ramp of slope dF/dt over one step: dF * tau / dt * (1 - e^{-dt/tau})
    step = np.diff(f) * np.where(dt > 0, tau / np.where(dt > 0, dt, 1.0) * (1.0 - decay), 1.0)
    memory = np.empty_like(f)
    memory[0] = f[0]
    h = float(f[0])
    # a first-order recursion: a Python loop over plain floats beats vectorising it for a press's ~1000 steps
    for k, (a, s) in enumerate(zip(decay.tolist(), step.tolist(), strict=True), start=1):
        h = a * h + s
        memory[k] = h
    return np.maximum((1.0 - relaxation) * f + relaxation * memory, 0.0)


def material_trace(trace: PhysicsTrace, material: MaterialRealism, softening: float) -> PhysicsTrace:
    """The trace with the material's softening (a factor on the force) and relaxation applied to force and pressure.

    Args:
        trace: the physics' (elastic) trace.
        material: relaxation parameters.
        softening: this press's stiffness factor (1 for a fresh spot).
    """
    elastic = np.asarray(trace.force, dtype=float) * softening
    force = relax_force(trace.t, elastic, material.relaxation, material.relaxation_time)
    base = np.asarray(trace.force, dtype=float)
    ratio = np.divide(force, base, out=np.zeros_like(force), where=base > 0)
    meta = dict(trace.meta, material_realism={"softening_factor": float(softening),
                                              "relaxation": float(material.relaxation),
                                              "relaxation_time_s": float(material.relaxation_time)})
    return replace(trace, force=force, sensel_pressure=trace.sensel_pressure * ratio[:, None, None], meta=meta)
