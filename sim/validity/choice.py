"""``auto``: the cheapest fidelity whose measured error (the validity table) is within the scenario's tolerance.

A press is placed in the table by what it feels (contact radius a = sqrt(R d) at its depth d):
- always its thickness: h / a and the Poisson ratio under the tip (``thickness`` rows of the nearest nu);
- a top layer: its thickness / a (``skin`` rows);
- an inclusion or a haptic-material boundary within reach (1.5 a + its depth from the press axis): its depth / a
  (``lump`` rows; the table's lumps are on the press axis, so an off-axis one is said to be outside the table);
- an edge within reach: its distance / a (``edge`` rows, measured on a cylinder pressed at its centre).
Each applicable family predicts an error: the largest over its rows within a factor 1.5 of the press's value (or,
past the table's largest value, the rows there: farther from the edge or thicker only helps); a press smaller than
anything measured has no prediction. A fidelity's predicted error is the worst over the families. Geometry rules
out what a fidelity cannot see: ``analytic`` needs a flat top under the whole contact, ``flex`` a box or cylinder.
The cheapest remaining fidelity within the tolerance wins (analytic, then rigid, then flex); if none is, the most
accurate one, and the reason says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from palpate.core.world.scene import ObjectSpec, material_index_at

ORDER = ("analytic", "rigid", "flex")
#: Reach of a lateral feature: 1.5 contact radii plus its depth (as the contact law's homogenisation).
REACH_A = 1.5
#: Rows within this factor of the press's feature count.
SPAN = 1.5


@dataclass(frozen=True)
class Situation:
    """Where a press sits in the validity table.

    Attributes:
        features: family -> the press's dimensionless value (see the module docstring).
        poisson: Poisson ratio under the tip.
        excluded: fidelity -> why the geometry rules it out.
        notes: what lies outside the table (said in the reason).
    """

    features: dict[str, float]
    poisson: float
    excluded: dict[str, str] = field(default_factory=dict)
    notes: tuple[str, ...] = ()


def _edge_distance(obj: ObjectSpec, x: float, y: float) -> float:
    d = np.array([x, y]) - np.asarray(obj.position, dtype=float)
    if obj.shape == "cylinder":
        return float(obj.size[0] - np.hypot(*d))
    half = np.asarray(obj.size[:2], dtype=float) / 2.0
    return float(np.min(half - np.abs(d)))


def _lateral_depth(obj: ObjectSpec, x: float, y: float, surface_z: float, a: float) -> tuple[float, bool] | None:
    """Depth (m) of the shallowest material change off the press axis within reach, and whether it is centred on
    the axis; None if the object is laterally uniform within reach."""
    names = [m.name for m in obj.materials()]
    depths = np.linspace(0.0, surface_z, 41)[:-1] + surface_z / 80.0
    theta = np.arange(12) * np.pi / 6.0
    for z in depths:
        radius = REACH_A * a + z
        rings = radius * np.linspace(0.2, 1.0, 4)
        pts = np.array([[x + r * math.cos(t), y + r * math.sin(t)] for r in rings for t in theta])
        inside = obj.contains_xy(pts)
        if not inside.any():
            continue
        p3 = np.column_stack([pts[inside], np.full(int(inside.sum()), surface_z - z)])
        idx = material_index_at(obj, p3, names)
        axis = material_index_at(obj, np.array([[x, y, surface_z - z]]), names)[0]
        if np.any(idx != axis):
            # centred: the same material all round each ring (an on-axis lump), else off the axis
            rings_same = idx.reshape(-1) if len(idx) != len(pts) else idx.reshape(len(rings), len(theta))
            centred = bool(len(idx) == len(pts) and np.all(rings_same == rings_same[:, :1]))
            return float(z), centred
    return None


def situation(obj: ObjectSpec, x: float, y: float, surface_z: float, depth: float, tip_radius: float) -> Situation:
    """Place a press of ``depth`` m at (x, y) on ``obj`` (top at ``surface_z``) in the validity table."""
    a = math.sqrt(tip_radius * max(depth, 1e-6))
    features: dict[str, float] = {"thickness": surface_z / a}
    excluded: dict[str, str] = {}
    notes: list[str] = []
    mats = obj.materials()
    under = material_index_at(obj, np.array([[x, y, surface_z - 1e-6]]), [m.name for m in mats])[0]
    poisson = float(mats[max(int(under), 0)].poisson)
    if obj.shape == "mesh":
        excluded["analytic"] = "a mesh top is curved or faceted"
        excluded["flex"] = "flex models boxes and cylinders only"
    else:
        edge = _edge_distance(obj, x, y)
        if edge < 1.2 * a:
            excluded["analytic"] = f"the contact reaches the edge {edge * 1e3:.1f} mm away"
        if edge < REACH_A * a + surface_z:
            features["edge"] = max(edge, 1e-6) / a
            if obj.shape == "box":
                notes.append("a straight edge (the table's edges are a cylinder's)")
    if obj.layers and obj.layers[0].thickness < surface_z:
        features["skin"] = obj.layers[0].thickness / a
    lateral = _lateral_depth(obj, x, y, surface_z, a)
    if lateral is not None:
        z, centred = lateral
        features["lump"] = max(z, 0.5e-3) / a
        if not centred:
            notes.append("material changing off the press axis (the table's lumps are on it)")
    return Situation(features, poisson, excluded, tuple(notes))


def _family_error(rows: list[dict], rung: str, value: float) -> float:
    if not rows:
        return math.inf
    feats = np.array([r["feature"] for r in rows])
    if value < feats.min() / SPAN:
        return math.inf  # smaller than anything measured
    near = (feats >= value / SPAN) & (feats <= value * SPAN)
    if not near.any():
        near = feats >= feats.max() / SPAN if value > feats.max() else np.abs(np.log(feats / value)) == np.min(
            np.abs(np.log(feats / value)))
    errs = [rows[i]["error"].get(rung) for i in np.nonzero(near)[0]]
    return max((abs(e) if e is not None else math.inf) for e in errs)


def predicted_errors(table: dict, sit: Situation) -> dict[str, float]:
    """Predicted |force error| per fidelity for a situation (inf where unknown or excluded)."""
    rows = table["rows"]
    out = {}
    for rung in ORDER:
        if rung in sit.excluded:
            out[rung] = math.inf
            continue
        worst = 0.0
        for family, value in sit.features.items():
            fam = [r for r in rows if r["family"] == family]
            if family == "thickness" and fam:
                nus = np.array([r["poisson"] for r in fam])
                best = nus[np.argmin(np.abs(nus - sit.poisson))]
                fam = [r for r in fam if r["poisson"] == best]
            worst = max(worst, _family_error(fam, rung, value))
        out[rung] = worst
    return out


def choose(table: dict, sit: Situation, tolerance: float, name: str) -> tuple[str, str]:
    """(fidelity, reason) for a situation under ``tolerance`` (fraction)."""
    errs = predicted_errors(table, sit)
    where = ", ".join(f"{k} {v:.2g}" for k, v in sit.features.items())
    said = "; ".join(f"{k}: {v:.1%}" if math.isfinite(v) else f"{k}: outside the table" for k, v in errs.items())
    extra = "".join(f"; {k} ruled out: {v}" for k, v in sit.excluded.items())
    extra += "".join(f"; note: {n}" for n in sit.notes)
    for rung in ORDER:
        if errs[rung] <= tolerance:
            return rung, (f"{name}: {rung} is the cheapest within the {tolerance:.0%} tolerance (validity table at "
                          f"{where}, nu {sit.poisson:g}: {said}{extra})")
    finite = {k: v for k, v in errs.items() if math.isfinite(v)}
    best = min(finite, key=finite.get) if finite else next(r for r in ORDER if r not in sit.excluded)
    return best, (f"{name}: no fidelity is within the {tolerance:.0%} tolerance; {best} is the most accurate "
                  f"(validity table at {where}, nu {sit.poisson:g}: {said}{extra})")
