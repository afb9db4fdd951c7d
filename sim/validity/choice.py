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
out what a fidelity cannot see: ``analytic`` and ``bem`` need a flat top under the whole contact (bem also 2 mm of
it beyond the contact), ``flex`` a box or cylinder;
and what a fidelity refuses (:mod:`palpate.sim.limits`: a press too deep for the material over the base, a Poisson
ratio or a layer it does not hold) rules it out the same way (every rung ruled out: ValidationError with the reasons).
Where the material changes off the press axis within reach (a wall, a map's boundary, a lump beside the axis), the
taxel image matters too: the image table (:mod:`.image_table`, against the 3-D FE) must pass the family (``wall``
where the change reaches the surface, else ``lump``; a family the image table has not measured leaves the choice
to the force rule) for a rung to be chosen, and its force error there is the rung's prediction; ``analytic`` and
``rigid`` render an axisymmetric image (their force beside a wall is the surface solve's), so their images fail
walls.
The cheapest remaining fidelity within the tolerance wins (analytic, then bem, then rigid, then flex); if none is,
the most accurate one, and the reason says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import ObjectSpec, material_index_at
from palpate.sim.analytic import material_under
from palpate.sim.limits import refusal
from palpate.sim.validity.image_table import RMS_LIMIT, ImageTable, load_image_table
from palpate.sim.validity.table import ValidityRow, ValidityTable, load_table

ORDER = ("analytic", "bem", "rigid", "flex")
#: A lateral change shallower than this (m) is a wall: it reaches the surface.
WALL_DEPTH = 0.5e-3
#: The families a press can be placed by, in the order its reason lists them.
FEATURES = ("thickness", "edge", "skin", "lump")
#: Depth of the first sample of a lateral change, m: just under the surface.
SURFACE_SAMPLE = 0.1e-3
#: Reach of a lateral feature: 1.5 contact radii plus its depth (as the contact law's homogenisation).
REACH_A = 1.5
#: Rows within this factor of the press's feature count.
SPAN = 1.5


@dataclass(frozen=True)
class Situation:
    """Where a press sits in the validity table: its dimensionless value in each family that applies (see the
    module docstring; None where the family does not apply).

    Attributes:
        thickness: thickness / a.
        poisson: Poisson ratio under the tip.
        edge: distance to an edge within reach / a.
        skin: top layer's thickness / a.
        lump: depth of a material change within reach / a.
        excluded: fidelity -> why the geometry rules it out.
        notes: what lies outside the table (said in the reason).
        image: the image table's family ("wall" or "lump") where material changes off the press axis within
            reach, else None.
    """

    thickness: float
    poisson: float
    edge: float | None = None
    skin: float | None = None
    lump: float | None = None
    excluded: dict[str, str] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    image: str | None = None

    def families(self) -> tuple[str, ...]:
        """The families that apply, in the order of FEATURES."""
        return tuple(f for f in FEATURES if self.value(f) is not None)

    def value(self, family: str) -> float | None:
        """The press's value in ``family`` (one of FEATURES), None where it does not apply."""
        if family not in FEATURES:
            raise ValueError(f"Situation: no family {family!r}; one of {FEATURES}")
        return getattr(self, family)


@dataclass(frozen=True)
class Choice:
    """What ``auto`` picked for a press, and why.

    Attributes:
        fidelity: the fidelity to press with.
        reason: one line saying where the press sits in the table and with what predicted errors.
        predicted: fidelity -> predicted |relative force error| (inf where unknown or ruled out); empty when the
            fidelity was set rather than chosen.
    """

    fidelity: str
    reason: str
    predicted: dict[str, float] = field(default_factory=dict)


def _edge_distance(obj: ObjectSpec, x: float, y: float) -> float:
    d = np.array([x, y]) - np.asarray(obj.position, dtype=float)
    if obj.shape == "cylinder":
        return float(obj.size[0] - np.hypot(*d))
    half = np.asarray(obj.size[:2], dtype=float) / 2.0
    return float(np.min(half - np.abs(d)))


@dataclass(frozen=True)
class LateralChange:
    """The shallowest material change off the press axis within reach: its depth below the top, m, whether it is
    centred on the axis (the same material all round each ring: an on-axis lump), and whether the material found
    there also differs at the surface (a wall beyond the surface's reach, found by a deeper, wider ring)."""

    depth: float
    centred: bool
    surface: bool = False


def _lateral_depth(obj: ObjectSpec, x: float, y: float, surface_z: float, a: float) -> LateralChange | None:
    """The shallowest material change off the press axis within reach; None if the object is laterally uniform
    within reach."""
    names = [m.name for m in obj.materials()]
    # the slab midpoints, led by one just under the surface: a change that reaches the surface is a wall whatever
    # the object's height (the first midpoint of a 40 mm block lies 0.5 mm down, at WALL_DEPTH itself)
    depths = np.linspace(0.0, surface_z, 41)[:-1] + surface_z / 80.0
    depths = np.concatenate([[min(SURFACE_SAMPLE, depths[0])], depths])
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
            top = surface_z - depths[0]
            odd = p3[idx != axis]
            at_top = material_index_at(obj, np.column_stack([odd[:, :2], np.full(len(odd), top)]), names)
            axis_top = material_index_at(obj, np.array([[x, y, top]]), names)[0]
            return LateralChange(depth=float(z), centred=centred, surface=bool(np.all(at_top != axis_top)))
    return None


def situation(obj: ObjectSpec, x: float, y: float, surface_z: float, depth: float, tip_radius: float) -> Situation:
    """Place a press of ``depth`` m at (x, y) on ``obj`` (top at ``surface_z``) in the validity table."""
    a = math.sqrt(tip_radius * max(depth, 1e-6))
    edge_value = skin = lump = None
    excluded: dict[str, str] = {}
    notes: list[str] = []
    poisson = float((material_under(obj, x, y, surface_z) or obj.materials()[0]).poisson)
    if obj.shape == "mesh":
        excluded["analytic"] = excluded["bem"] = "a mesh top is curved or faceted"
        excluded["flex"] = "flex models boxes and cylinders only"
    else:
        edge = _edge_distance(obj, x, y)
        if edge < 1.2 * a:
            excluded["analytic"] = f"the contact reaches the edge {edge * 1e3:.1f} mm away"
        if edge < 1.2 * a + 2e-3:
            # bem leaves the free side's compliance out (cells off the object carry nothing)
            excluded["bem"] = f"the contact comes within 2 mm of the edge {edge * 1e3:.1f} mm away"
        if edge < REACH_A * a + surface_z:
            edge_value = max(edge, 1e-6) / a
            if obj.shape == "box":
                notes.append("a straight edge (the table's edges are a cylinder's)")
    if obj.layers and obj.layers[0].thickness < surface_z:
        skin = obj.layers[0].thickness / a
    lateral = _lateral_depth(obj, x, y, surface_z, a)
    image = None
    if lateral is not None:
        lump = max(lateral.depth, 0.5e-3) / a
        if not lateral.centred:
            # a wall found only by a deeper, wider ring lies beyond the image's reach: no image family applies
            image = "wall" if lateral.depth < WALL_DEPTH else (None if lateral.surface else "lump")
            notes.append("material changing off the press axis (the table's lumps are on it)")
    for rung in ORDER:  # what a rung would refuse (palpate.sim.limits) rules it out too
        why = refusal(rung, obj, depth, surface_z)
        if why is not None and rung not in excluded:
            excluded[rung] = why
    return Situation(thickness=surface_z / a, poisson=poisson, edge=edge_value, skin=skin, lump=lump,
                     excluded=excluded, notes=tuple(notes), image=image)


def _family_error(rows: list[ValidityRow], rung: str, value: float) -> float:
    if not rows:
        return math.inf
    feats = np.array([r.feature for r in rows])
    if value < feats.min() / SPAN:
        return math.inf  # smaller than anything measured
    near = (feats >= value / SPAN) & (feats <= value * SPAN)
    if not near.any():
        near = feats >= feats.max() / SPAN if value > feats.max() else np.abs(np.log(feats / value)) == np.min(
            np.abs(np.log(feats / value)))
    errs = [rows[i].error.get(rung) for i in np.nonzero(near)[0]]
    return max((abs(e) if e is not None else math.inf) for e in errs)


def image_exclusions(images: ImageTable, sit: Situation) -> dict[str, str]:
    """Fidelity -> why its image rules it out of a press whose material changes off the axis (empty otherwise)."""
    if sit.image is None or not images.measures(sit.image):
        return {}
    out = {}
    for rung in ORDER:
        _, why = images.verdict(rung, sit.image)
        if why is not None:
            out[rung] = why
    return out


def predicted_errors(table: ValidityTable, sit: Situation, images: ImageTable | None = None) -> dict[str, float]:
    """Predicted |relative force error| per fidelity for a situation (inf where unknown or excluded); with a
    lateral change off the axis, the image table's force error for its family (and inf where the image fails)."""
    rows = table.rows
    out = {}
    blind = image_exclusions(images, sit) if images is not None else {}
    for rung in ORDER:
        if rung in sit.excluded or rung in blind:
            out[rung] = math.inf
            continue
        if sit.image is not None and images is not None and images.measures(sit.image):
            # the image table's cases hold the off-axis change itself; the other families still apply
            out[rung] = max(images.verdict(rung, sit.image)[0],
                            _other_families(table, sit, rung, skip=("lump",)))
            continue
        worst = 0.0
        for family in sit.families():
            fam = [r for r in rows if r.family == family]
            if family == "thickness" and fam:
                nus = np.array([r.poisson for r in fam])
                best = nus[np.argmin(np.abs(nus - sit.poisson))]
                fam = [r for r in fam if r.poisson == best]
            worst = max(worst, _family_error(fam, rung, sit.value(family)))
        out[rung] = worst
    return out


def _other_families(table: ValidityTable, sit: Situation, rung: str, skip: tuple[str, ...]) -> float:
    """The worst predicted error of ``rung`` over the situation's families other than ``skip``; 0 if none apply."""
    worst = 0.0
    for family in sit.families():
        if family in skip or family == "thickness":
            continue
        worst = max(worst, _family_error([r for r in table.rows if r.family == family], rung, sit.value(family)))
    return worst


def image_note(rung: str, images: ImageTable | None) -> str | None:
    """What a reason adds when it names ``rung``: how far the image table finds its image off on plain blocks (flex
    is chosen where no cheaper rung holds the geometry, so its image is never judged against a feature there)."""
    if rung != "flex":
        return None
    rows = images.measured(rung, "block") if images is not None else []
    if not rows:
        return "flex's taxel image is not checked against the FE (the image table holds no flex rows): use its force"
    worst = max(r.rms_share for r in rows)
    if worst <= RMS_LIMIT:
        return None
    return (f"flex's taxel image is up to {worst:.0%} of the peak off per sensel on plain blocks (the image table): "
            "use its force, not its image")


def choose(table: ValidityTable, sit: Situation, tolerance: float, name: str,
           images: ImageTable | None = None) -> Choice:
    """The cheapest fidelity for a situation under ``tolerance`` (fraction), the reason and the predicted errors;
    ``name`` (the object's) starts the reason; ``images`` the image table (needed where the material changes off the
    press axis, and to say how far flex's image is off when flex is chosen)."""
    choice = _choose(table, sit, tolerance, name, images)
    note = image_note(choice.fidelity, images)
    if note is None:
        return choice
    return Choice(choice.fidelity, f"{choice.reason}; note: {note}", choice.predicted)


def _choose(table: ValidityTable, sit: Situation, tolerance: float, name: str,
            images: ImageTable | None = None) -> Choice:
    errs = predicted_errors(table, sit, images)
    where = ", ".join(f"{k} {sit.value(k):.2g}" for k in sit.families())
    if sit.image is not None and images is not None and images.measures(sit.image):
        where += f", a {sit.image} off the press axis"
    said = "; ".join(f"{k}: {v:.1%}" if math.isfinite(v) else f"{k}: outside the table" for k, v in errs.items())
    ruled = dict(sit.excluded)
    if images is not None:
        ruled.update({k: v for k, v in image_exclusions(images, sit).items() if k not in ruled})
    extra = "".join(f"; {k} ruled out: {v}" for k, v in ruled.items())
    extra += "".join(f"; note: {n}" for n in sit.notes)
    for rung in ORDER:
        if errs[rung] <= tolerance:
            return Choice(rung, f"{name}: {rung} is the cheapest within the {tolerance:.0%} tolerance (validity "
                          f"table at {where}, nu {sit.poisson:g}: {said}{extra})", errs)
    if all(rung in sit.excluded for rung in ORDER):
        reasons = list(dict.fromkeys(sit.excluded[r] for r in ORDER))
        raise ValidationError(f"{name}: no fidelity holds this press: {'; '.join(reasons)}")
    if (sit.image is not None and images is not None and images.measures(sit.image)
            and not any(math.isfinite(v) for v in errs.values())):
        # no rung's image holds the family: the closest image among the rungs whose force holds it (else the
        # rung whose force is nearest), said as such
        allowed = tuple(r for r in ORDER if r not in sit.excluded)
        closest = images.closest(allowed, sit.image, tolerance)
        if closest is not None:
            rung, wrong, share = closest
            return Choice(rung, f"{name}: no fidelity's image is within the image table's limits over "
                          f"{sit.image}s; {rung}'s is the closest (asymmetry wrong in {wrong:.0%} of the measured "
                          f"presses, rms up to {share:.0%} of the peak per sensel; "
                          f"validity table at {where}, nu {sit.poisson:g}: {said}{extra})", errs)
    finite = {k: v for k, v in errs.items() if math.isfinite(v)}
    # with nothing measured to prefer, the cheapest rung the geometry allows (bem holds no validity-table rows)
    allowed = [r for r in ORDER if r not in sit.excluded]
    best = min(finite, key=finite.get) if finite else next((r for r in allowed if r != "bem"), allowed[0])
    return Choice(best, f"{name}: no fidelity is within the {tolerance:.0%} tolerance; {best} is the most accurate "
                  f"(validity table at {where}, nu {sit.poisson:g}: {said}{extra})", errs)


#: Default tolerance of ``auto``: the largest predicted force error against the reference, fraction.
DEFAULT_TOLERANCE = 0.05


def explain_fidelity(obj: ObjectSpec, target: PressTarget, radius: float, *, tolerance: float = DEFAULT_TOLERANCE,
                     table: ValidityTable | None = None, depth: float | None = None, surface_z: float | None = None,
                     images: ImageTable | None = None) -> Choice:
    """The cheapest fidelity within ``tolerance`` for pressing ``obj`` at ``target``, a one-line reason and the
    predicted errors.

    Args:
        depth: the press's depth, m (default the target's, or 0.25 tip radii for a force-only target).
        table: a loaded validity table (default the shipped one).
        images: a loaded image table (default the shipped one).
        surface_z: the top's height at the target, m (default the object's height).
    """
    table = load_table() if table is None else table
    d = depth if depth is not None else (target.depth if target.depth is not None else 0.25 * radius)
    top = obj.height if surface_z is None else surface_z
    sit = situation(obj, target.x, target.y, top, d, radius)
    if images is None:
        images = load_image_table()
    return choose(table, sit, tolerance, obj.name, images)


def choose_fidelity(obj: ObjectSpec, target: PressTarget, radius: float, **kwargs) -> str:
    """The fidelity :func:`explain_fidelity` picks."""
    return explain_fidelity(obj, target, radius, **kwargs).fidelity
