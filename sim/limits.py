"""What each fidelity holds: the presses a rung refuses rather than answer wrongly.

- **Depth over the rigid base** (every rung): a press at most MAX_DEPTH_OVER_THICKNESS of the material over the
  table at the press point (a block's thickness, a layer stack's total). The contact law is linear elastic on a
  base the tip never reaches: at a depth equal to the thickness the tip would touch the table, where a real force
  grows without bound and the law's stays finite (11 N at 200% nominal strain, silently). The validity table
  (models/validity_table.json) measured the thickness family down to 1 mm into 2 mm, half the thickness (its cases
  stop at 60%, and the next depth, 2 mm into 2 mm, is past that), with every rung within 6% of the FE there; past
  it nothing was measured, and flex was +8% to +12% at 60-75% of a 2 mm block.
- **Poisson ratio** (MAX_POISSON, per rung): analytic and rigid share the contact law, exact linear elasticity,
  within 0.25% of the axisymmetric Q2 FE reference at nu 0.499 on 2 and 20 mm blocks and at 0.4999 on 2 mm (the
  scenario file's own bound); flex's trilinear cells (selective reduced integration) were measured to nu 0.49 (the
  validity table; +3% on a 20 mm block pressed 2 mm) and stiffen beyond it (+7.5% at 0.495, +11% with solver
  warnings on most steps at 0.499).
- **Thin layers** (MIN_LAYER, per rung): flex samples each 5 mm cell's material at 4 points per edge, so a soft
  skin thinner than an eighth of its top cell (0.63 mm) is not seen at all (the bare block, +68% to +80% on a 0.5 mm
  skin), and a 0.2 mm stiff skin was +64% at 1 mm; the validity table's thinnest skins, 1 mm, are within 7%.
  analytic and rigid (the layered contact law) hold a 20 kPa skin on 200 kPa within 1.2% of the FE down to 0.05 mm
  (0.1 and 0.2 mm: 0.2%), pressed 0.5-2 mm; at 0.02 mm the law's tables no longer resolve the layer (its force
  came out 40% over the bare base's) and at 0.01 mm it fails. bem (the same layered stack as boundary elements of
  0.5 mm) holds 0.25 and 0.5 mm skins within 0.4% of the law (tests/test_bem.py), and was measured to nu 0.49.

Each check returns the refusal's one-line reason (naming the limit and what helps) or None; :func:`check_holds`
raises it as a ValidationError, and ``auto`` (:mod:`palpate.sim.validity.choice`) rules out a rung that would
refuse.
"""

from __future__ import annotations

from palpate.core.errors import ValidationError
from palpate.core.world.scene import ObjectSpec

#: Deepest press, as a share of the material over the rigid base at the press point (see the module docstring).
MAX_DEPTH_OVER_THICKNESS = 0.5
#: Largest Poisson ratio each fidelity holds (see the module docstring).
MAX_POISSON = {"analytic": 0.4999, "bem": 0.49, "rigid": 0.4999, "flex": 0.49}
#: Thinnest layer each fidelity resolves, m (see the module docstring).
MIN_LAYER = {"analytic": 5.0e-5, "bem": 2.5e-4, "rigid": 5.0e-5, "flex": 1.0e-3}


def depth_refusal(depth: float, thickness: float) -> str | None:
    """Why a press ``depth`` m deep into ``thickness`` m of material over the rigid base is refused, or None."""
    limit = MAX_DEPTH_OVER_THICKNESS * thickness
    # a press scaled to stop exactly at the limit may land a rounding error past it
    if depth <= limit * (1.0 + 1e-9):
        return None
    return (f"a press {depth * 1e3:.2f} mm deep is over {MAX_DEPTH_OVER_THICKNESS:.0%} of the "
            f"{thickness * 1e3:.2f} mm of material over the rigid base (depth limit {limit * 1e3:.2f} mm, the "
            f"deepest share the validity table measured): press at most {limit * 1e3:.2f} mm deep (a shallower press "
            f"or a lower force target) or use a thicker sample")


def poisson_refusal(obj: ObjectSpec, fidelity: str) -> str | None:
    """Why ``fidelity`` refuses ``obj`` for a Poisson ratio over what it holds (MAX_POISSON), or None."""
    limit = MAX_POISSON.get(fidelity)
    if limit is None:
        return None
    over = [m for m in obj.materials() if m.poisson > limit]
    if not over:
        return None
    m = max(over, key=lambda mat: mat.poisson)
    holds = sorted((r for r, v in MAX_POISSON.items() if v >= m.poisson), key=list(MAX_POISSON).index)
    advice = (f"use fidelity {' or '.join(repr(r) for r in holds)} (up to {MAX_POISSON[holds[0]]:g})" if holds
              else "")
    return (f"fidelity {fidelity!r} holds a Poisson ratio up to {limit:g}; material {m.name!r} has {m.poisson:g}: "
            f"use a Poisson ratio of at most {limit:g}" + (f" or {advice}" if advice else ""))


def layer_refusal(obj: ObjectSpec, fidelity: str) -> str | None:
    """Why ``fidelity`` refuses ``obj`` for a layer thinner than it resolves (MIN_LAYER), or None."""
    limit = MIN_LAYER.get(fidelity)
    thin = [la for la in obj.layers if limit is not None and la.thickness < limit]
    if not thin:
        return None
    la = min(thin, key=lambda layer: layer.thickness)
    holds = [r for r, v in MIN_LAYER.items() if v <= la.thickness]
    advice = "".join(f"use fidelity {r!r} (layers from {MIN_LAYER[r] * 1e3:g} mm) or " for r in holds[:1])
    return (f"fidelity {fidelity!r} resolves layers from {limit * 1e3:g} mm; layer {la.material.name!r} of "
            f"{obj.name!r} is {la.thickness * 1e3:.3g} mm thick: {advice}use a layer of at least {limit * 1e3:g} mm "
            "(or leave it out)")


def refusal(fidelity: str, obj: ObjectSpec, depth: float, thickness: float) -> str | None:
    """Why ``fidelity`` refuses a press ``depth`` m deep into ``obj`` with ``thickness`` m of material over the rigid
    base at the press point (the top's height there), or None if it holds it."""
    return (depth_refusal(depth, thickness) or poisson_refusal(obj, fidelity) or layer_refusal(obj, fidelity))


def check_holds(fidelity: str, obj: ObjectSpec, profile, context: str = "") -> None:
    """Raise ValidationError if ``fidelity`` does not hold the press ``profile`` (meta "depth", surface_z: the
    material over the table, which stands at z = 0) on ``obj`` (see the module docstring)."""
    why = refusal(fidelity, obj, float(profile.meta.get("depth", 0.0)), float(profile.surface_z))
    if why is not None:
        raise ValidationError(f"{why}{context}")
