"""What real foams and rubbers add to an elastic contact: a foam's stress plateau, relaxation under load, softening
over repeated presses.

A cellular material (a sponge, an open-cell foam) is linear-elastic only up to a small strain, ~5%: then its cell
walls buckle and the stress stays on a plateau until the cells close (densification, at strains of 0.5-0.9 that no
palpation reaches; Gibson & Ashby, Cellular Solids, 2nd ed. 1997, ch. 5). Under a sphere of radius R the mean strain
of the contact is ~0.2 a / R (Tabor's representative strain), with a = sqrt(R d) the contact radius at indentation
d; Hertz's mean pressure grows in proportion to it. Past the plateau strain eps_p, i.e. past the indentation
d_p = R (eps_p / 0.2)^2 (:func:`plateau_depth`), the mean pressure stays at the plateau's (a foam indented by a
sphere has a hardness equal to its plateau stress: it crushes under the indenter, with no lateral spread), so the
force grows as the contact area: F = F_el(d) sqrt(d_p / d) (:func:`plateau_factor`), as d instead of Hertz's
d^1.5. The plateau applies to the elastic force the physics computed, before relaxation. Densification, which the
mean strain under a fingertip does not reach, is felt where the strain under the tip's axis or across a thin sample
is much larger than the mean: an optional onset eps_d (at d_d likewise) past which the force grows by d / d_d
(:func:`densify_factor`), a phenomenological form for a sponge whose pushback keeps rising deep into a press.

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

#: Tabor's representative strain of a sphere's contact: mean strain = TABOR_STRAIN * a / R.
TABOR_STRAIN = 0.2


def plateau_depth(strain: float, radius: float) -> float:
    """The indentation, m, at which a sphere of ``radius`` m reaches a mean contact strain ``strain`` (0: none)."""
    return float(radius * (strain / TABOR_STRAIN) ** 2)


def plateau_factor(indentation: np.ndarray, depth: float) -> np.ndarray:
    """The force past a stress plateau reached at indentation ``depth`` m, relative to the elastic force.

    1 up to ``depth`` (and everywhere when ``depth`` is 0: no plateau), sqrt(depth / d) beyond: the mean pressure
    stays at the plateau's while the contact area grows.
    """
    d = np.asarray(indentation, dtype=float)
    if depth <= 0:
        return np.ones_like(d)
    return np.sqrt(depth / np.maximum(d, depth))


def plateau_depth_for_force(depth_for_force, force: float, depth: float, iterations: int = 40) -> float:
    """The indentation, m, at which a material with a plateau from ``depth`` m pushes back with ``force`` N.

    ``depth_for_force`` is its elastic law. Solves F_el(d) plateau_factor(d) = F by fixed-point iteration
    d <- depth_for_force(F / plateau_factor(d)), monotonic from the elastic depth; on a Hertz-like law the error
    shrinks threefold per step.
    """
    d = float(depth_for_force(force))
    if depth <= 0 or not np.isfinite(d):
        return d
    for _ in range(iterations):
        nxt = float(depth_for_force(force / float(plateau_factor(np.array(d), depth))))
        if not np.isfinite(nxt) or abs(nxt - d) <= 1e-12 + 1e-9 * d:
            return nxt
        d = nxt
    return d


def densify_factor(indentation: np.ndarray, depth: float) -> np.ndarray:
    """The force past densification reached at indentation ``depth`` m, relative to the force before it.

    1 up to ``depth`` (and everywhere when ``depth`` is 0: none), d / depth beyond: the collapsed cells under the
    contact touch and the mean pressure rises with the indentation again.
    """
    d = np.asarray(indentation, dtype=float)
    if depth <= 0:
        return np.ones_like(d)
    return np.maximum(d, depth) / depth


def cellular_factor(indentation: np.ndarray, plateau: float, densify: float) -> np.ndarray:
    """:func:`plateau_factor` times :func:`densify_factor` (either depth 0: that one off)."""
    f = plateau_factor(indentation, plateau)
    return f if densify <= 0 else f * densify_factor(indentation, densify)


#: Doublings of the bracket :func:`cellular_depth_for_force` tries (2^60 times the elastic depth) before it answers
#: that no depth reaches the force.
MAX_DOUBLINGS = 60


def cellular_depth_for_force(depth_for_force, force: float, plateau: float, densify: float,
                             iterations: int = 60) -> float:
    """The indentation, m, at which a material with a plateau from ``plateau`` m and densification from ``densify``
    m pushes back with ``force`` N (``depth_for_force``: its elastic law); :func:`plateau_depth_for_force` when
    nothing densifies.

    The force F_el(d) g(d) grows with d, so d - depth_for_force(F / g(d)) does too: its root is found by regula
    falsi (Illinois) between the depth where g = 1 would put it and one that doubles until it brackets it; inf when
    the law answers inf (or NaN) before that, as :func:`plateau_depth_for_force` answers.
    """
    if densify <= 0:
        return plateau_depth_for_force(depth_for_force, force, plateau, iterations)

    def excess(d: float) -> float:
        return d - float(depth_for_force(force / float(cellular_factor(np.array(d), plateau, densify))))

    lo, hi = 0.0, float(depth_for_force(force))
    if not (np.isfinite(hi) and hi > 0):
        return hi  # no force needs no depth; a force beyond the law is beyond it here too
    f_lo, f_hi = excess(lo), excess(hi)
    for _ in range(MAX_DOUBLINGS):
        if f_hi >= 0:
            break
        lo, f_lo, hi = hi, f_hi, 2.0 * hi
        f_hi = excess(hi)
    if not f_hi >= 0:
        return float("inf")  # the law runs out (or answers NaN) before the material pushes back with the force
    side = 0
    for _ in range(iterations):
        d = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        f_d = excess(d)
        if abs(f_d) <= 1e-12 + 1e-9 * d:
            return d
        if f_d < 0:
            lo, f_lo = d, f_d
            f_hi = f_hi / 2 if side == -1 else f_hi
            side = -1
        else:
            hi, f_hi = d, f_d
            f_lo = f_lo / 2 if side == 1 else f_lo
            side = 1
    return 0.5 * (lo + hi)


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


def material_trace(trace: PhysicsTrace, material: MaterialRealism, softening: float,
                   plateau: float = 0.0, densify: float = 0.0) -> PhysicsTrace:
    """The trace with the material's plateau, densification and softening (factors on the force) and relaxation
    applied to force and pressure (the pressure in proportion, so the pad carries the force).

    Args:
        trace: the physics' (elastic) trace.
        material: relaxation parameters.
        softening: this press's stiffness factor (1 for a fresh spot).
        plateau: the indentation at which this press's material reaches its stress plateau, m (0: none;
            :func:`plateau_depth`).
        densify: the indentation at which it starts to densify, m (0: none; :func:`plateau_depth` of its strain).
    """
    elastic = np.asarray(trace.force, dtype=float) * softening
    if plateau > 0 or densify > 0:
        elastic = elastic * cellular_factor(np.maximum(trace.indentation, 0.0), plateau, densify)
    force = relax_force(trace.t, elastic, material.relaxation, material.relaxation_time)
    base = np.asarray(trace.force, dtype=float)
    ratio = np.divide(force, base, out=np.zeros_like(force), where=base > 0)
    record = {"softening_factor": float(softening), "relaxation": float(material.relaxation),
              "relaxation_time_s": float(material.relaxation_time)}
    if plateau > 0:
        record["plateau_depth_m"] = float(plateau)
    if densify > 0:
        record["densify_depth_m"] = float(densify)
    meta = dict(trace.meta, material_realism=record)
    return replace(trace, force=force, sensel_pressure=trace.sensel_pressure * ratio[:, None, None], meta=meta)
