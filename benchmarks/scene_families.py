"""Seeded scenes of many shape families, for measuring how exploration generalises.

benchmarks/exploration.py's own generator makes axis-aligned boxes two or more cells wide with walls kept away from
cell centres; settings tuned there need not hold elsewhere. Here each scene is a box whose surface layout is drawn
at 0.5 mm resolution by one of :data:`FAMILIES` and handed to the simulation as a haptic-material map (seed 002),
so its walls cut through the block at any angle and anywhere relative to the cells:

==============  ===============================================================================================
boxes           1-4 axis-aligned rectangles 1.2-4 cells wide
oblique         1-3 rectangles or half-planes at an oblique angle
curved          1-3 ellipses or smooth blobs (radial Fourier outlines) 1-3 cells across
stripes         1-3 straight stripes 0.7-1.3 cells wide, any orientation, half the block long or more
dots            2-6 features about one cell across
nested          2-3 shapes one inside the other, each of its own material
patchwork       a Voronoi tessellation of 3-8 regions
rings           1-2 annuli about one cell wide
mixed           a blob, a stripe and one or two dots
==============  ===============================================================================================

Every scene draws 2-4 of the four reference materials (soft 20 kPa, firm 50 kPa, medium 115 kPa, hard 450 kPa),
sometimes as a like-material 0.8-1.25x the reference's modulus, trains the memory on exactly those, and draws a cell
size of 10-20 mm and a grid of 7-15 x 6-12 cells whose origin is offset by a random fraction of a cell.

Seeds are split: :data:`TUNING_SEEDS` are the ones settings may be tuned on, :data:`REPORT_SEEDS` (from 100000 on)
are only reported. A scene's family is ``FAMILIES[seed % len(FAMILIES)]``, so any run of consecutive seeds covers
the families evenly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cache

import numpy as np

from palpate.core.world.haptic_material import HapticMaterialMap
from palpate.core.world.scenario import Scenario
from palpate.core.world.scenario_file import parse_scenario

#: Resolution of a scene's surface layout, mm.
PX_MM = 0.5
#: (name, Young's modulus kPa, Poisson ratio) of the reference materials, softest first.
REFERENCES = (("soft", 20.0, 0.3), ("firm", 50.0, 0.4), ("medium", 115.0, 0.45), ("hard", 450.0, 0.4))
FAMILIES = ("boxes", "oblique", "curved", "stripes", "dots", "nested", "patchwork", "rings", "mixed")
TUNING_SEEDS = range(0, 100000)
REPORT_SEEDS = range(100000, 200000)
HEIGHT_MM = 40.0
#: Young's modulus (kPa) of "firm" in the confused-memory variant: its plane-strain modulus E / (1 - nu^2) is 1.3%
#: above soft's, so the memory trained on them names the wrong one of the two in about a fifth of presses.
CONFUSED_FIRM_KPA = 18.7
#: Bumped whenever a seed's scene changes (caches of derived data are keyed on it).
GENERATOR_VERSION = 1


@dataclass(frozen=True)
class FamilyScene:
    """One generated scene: its layout and where the map lies.

    Attributes:
        seed, family: what drew it.
        cell_mm: map cell side, mm.
        size_mm: (sx, sy) of the block, mm; the block's corner is at the origin.
        grid_origin_mm, grid_cells: the map's corner (mm) and (nx, ny) cells.
        materials: the scene's materials as (name, like-reference, Young's modulus kPa, Poisson), slot order.
        references: the reference materials present (the memory's classes), softest first.
        labels: (ny_px, nx_px) slot index per PX_MM pixel, row 0 at y = 0.
        lumps: buried inclusions as TOML tables (``[[objects.inclusions]]``: material, shape, center_mm, size_mm);
            benchmarks/lump_scenes.py draws them.
    """

    seed: int
    family: str
    cell_mm: float
    size_mm: tuple[float, float]
    grid_origin_mm: tuple[float, float]
    grid_cells: tuple[int, int]
    materials: tuple[tuple[str, str, float, float], ...]
    references: tuple[str, ...]
    labels: np.ndarray
    confused: bool = False
    lumps: tuple[dict, ...] = ()

    def moduli(self) -> tuple[float, ...]:
        """Young's modulus (kPa) of each reference material, in ``references`` order."""
        return tuple(CONFUSED_FIRM_KPA if self.confused and r == "firm" else next(e for n, e, _ in REFERENCES if n == r)
                     for r in self.references)

    def with_confusion(self) -> FamilyScene:
        """The same layout with "firm" (and its like-materials) made to feel almost like "soft", so the memory
        trained on them confuses the two (scene unchanged when it has no firm material)."""
        scale = CONFUSED_FIRM_KPA / next(e for n, e, _ in REFERENCES if n == "firm")
        mats = tuple((n, like, round(e * scale, 2) if like == "firm" else e, nu) for n, like, e, nu in self.materials)
        return replace(self, materials=mats, confused=True)

    def material_map(self) -> HapticMaterialMap:
        """The layout as a haptic-material map over the block's top (one-hot probabilities)."""
        k = len(self.materials)
        onehot = (self.labels[..., None] == np.arange(k)).astype(float)
        return HapticMaterialMap(origin=(0.0, 0.0), cell_size=PX_MM * 1e-3, materials=[m[0] for m in self.materials],
                                 probabilities=onehot)

    def scenario_dict(self, policy: str = "raster", budget: int | None = None, objective: str | None = None,
                      fidelity: str = "analytic") -> dict:
        """The scene as a scenario dictionary (TOML schema) without its layout; :meth:`scenario` adds it."""
        nx, ny = self.grid_cells
        mats = [{"name": n, "young_kpa": e, "poisson": nu} | ({} if n == like else {"reference": False, "like": like})
                for n, like, e, nu in self.materials]
        for name, e, nu in zip(self.references, self.moduli(), (r[2] for r in REFERENCES if r[0] in self.references),
                               strict=True):
            if all(m[0] != name for m in self.materials):
                mats.append({"name": name, "young_kpa": e, "poisson": nu})
        # the memory's classes in palette order (softest first), whatever order the slots took
        mats.sort(key=lambda m: (m.get("reference", True) is False, [r[0] for r in REFERENCES].index(
            m.get("like", m["name"]))))
        sx, sy = self.size_mm
        obj = {"name": f"scene{self.seed}", "size_mm": [sx, sy, HEIGHT_MM], "position_mm": [sx / 2, sy / 2],
               "material": self.materials[0][0], "grid_origin_mm": list(self.grid_origin_mm),
               "grid_cells": [nx, ny], "regions": [[c + 1, r + 1] for r in range(1, ny, 3) for c in range(1, nx, 3)]}
        if self.lumps:
            obj["inclusions"] = [dict(lump) for lump in self.lumps]
        ex = {"policy": policy, "budget": budget or nx * ny, "presses_per_region": 1, "cell_mm": self.cell_mm,
              "depth_mm": 4.0, "max_force_n": 10.0, "variability": "human"}
        if objective is not None:
            ex["objective"] = objective
        return {"scenario": {"name": f"family_{self.family}_{self.seed}", "seed": self.seed, "fidelity": fidelity},
                "materials": mats, "training": {"presses_per_material": 10, "depth_mm": 4.0, "max_force_n": 10.0},
                "exploration": ex, "objects": [obj], "outputs": {"figures": False, "haptic_material": False}}

    def scenario(self, policy: str = "raster", budget: int | None = None, objective: str | None = None,
                 fidelity: str = "analytic") -> Scenario:
        """The validated scenario with the layout installed as the block's haptic-material map."""
        sc = parse_scenario(self.scenario_dict(policy, budget, objective, fidelity), f"family_{self.family}")
        entry = sc.objects[0]
        spec = replace(entry.spec, material_map=self.material_map(),
                       map_materials=tuple(sc.materials[m[0]].material for m in self.materials))
        return replace(sc, objects=(replace(entry, spec=spec),))


def is_report_seed(seed: int) -> bool:
    return seed in REPORT_SEEDS


# ---- shapes on the pixel grid (coordinates in mm) --------------------------------------------------------------

def _rot(x: np.ndarray, y: np.ndarray, cx: float, cy: float, angle: float) -> tuple[np.ndarray, np.ndarray]:
    c, s = math.cos(angle), math.sin(angle)
    dx, dy = x - cx, y - cy
    return c * dx + s * dy, -s * dx + c * dy


def _rect(x, y, cx, cy, w, h, angle=0.0) -> np.ndarray:
    u, v = _rot(x, y, cx, cy, angle)
    return (np.abs(u) <= w / 2) & (np.abs(v) <= h / 2)


def _ellipse(x, y, cx, cy, a, b, angle=0.0) -> np.ndarray:
    u, v = _rot(x, y, cx, cy, angle)
    return (u / a) ** 2 + (v / b) ** 2 <= 1.0


def _blob(rng, x, y, cx, cy, r0) -> np.ndarray:
    """A smooth closed outline: radius r0 (1 + sum of 2-4 low harmonics of amplitude <= 0.25)."""
    theta = np.arctan2(y - cy, x - cx)
    r = np.full_like(theta, 1.0)
    for k in range(2, 2 + int(rng.integers(1, 4))):
        r += rng.uniform(0.05, 0.25) / k * np.cos(k * theta + rng.uniform(0, 2 * np.pi))
    return np.hypot(x - cx, y - cy) <= r0 * r


def _segment(x, y, x0, y0, x1, y1, width) -> np.ndarray:
    """Points within width/2 of the segment (x0, y0)-(x1, y1): a straight stripe with round ends."""
    dx, dy = x1 - x0, y1 - y0
    t = np.clip(((x - x0) * dx + (y - y0) * dy) / max(dx * dx + dy * dy, 1e-12), 0.0, 1.0)
    return np.hypot(x - (x0 + t * dx), y - (y0 + t * dy)) <= width / 2


def _oblique_angle(rng) -> float:
    """An angle at least 10 degrees away from both axes, rad."""
    return float(rng.uniform(math.radians(10), math.radians(80)) * rng.choice([1, -1]))


def _stripe_angle(rng) -> float:
    return float(rng.choice([0.0, math.pi / 2, math.pi / 4, -math.pi / 4, rng.uniform(0, math.pi)]))


def _masks(family: str, rng, x, y, sx, sy, c) -> list[np.ndarray]:
    """The feature masks of one family, painted in order over the background (c = cell side, mm)."""
    def centre(margin=0.0):
        return rng.uniform(margin, sx - margin), rng.uniform(margin, sy - margin)

    out = []
    if family == "boxes":
        for _ in range(int(rng.integers(1, 5))):
            out.append(_rect(x, y, *centre(c), rng.uniform(1.2, 4) * c, rng.uniform(1.2, 4) * c))
    elif family == "oblique":
        for _ in range(int(rng.integers(1, 4))):
            if rng.random() < 0.35:
                a = _oblique_angle(rng)
                px, py = centre(2 * c)
                out.append((x - px) * math.sin(a) - (y - py) * math.cos(a) > 0)
            else:
                out.append(_rect(x, y, *centre(c), rng.uniform(1.5, 4.5) * c, rng.uniform(1.5, 3.5) * c,
                                 _oblique_angle(rng)))
    elif family == "curved":
        for _ in range(int(rng.integers(1, 4))):
            if rng.random() < 0.5:
                out.append(_ellipse(x, y, *centre(c), rng.uniform(0.6, 1.8) * c, rng.uniform(0.6, 1.8) * c,
                                    rng.uniform(0, np.pi)))
            else:
                out.append(_blob(rng, x, y, *centre(c), rng.uniform(0.7, 1.8) * c))
    elif family == "stripes":
        for _ in range(int(rng.integers(1, 4))):
            a = _stripe_angle(rng)
            half = rng.uniform(0.25, 0.6) * math.hypot(sx, sy)
            cx, cy = centre(c)
            out.append(_segment(x, y, cx - half * math.cos(a), cy - half * math.sin(a), cx + half * math.cos(a),
                                cy + half * math.sin(a), rng.uniform(0.7, 1.3) * c))
    elif family == "dots":
        for _ in range(int(rng.integers(2, 7))):
            s = rng.uniform(0.8, 1.5) * c
            if rng.random() < 0.5:
                out.append(_rect(x, y, *centre(s / 2), s, s, rng.uniform(0, np.pi / 2)))
            else:
                out.append(_ellipse(x, y, *centre(s / 2), s / 2, s / 2))
    elif family == "nested":
        cx, cy = centre(0.3 * min(sx, sy))
        w, h = rng.uniform(0.45, 0.8) * sx, rng.uniform(0.45, 0.8) * sy
        angle = rng.uniform(-0.3, 0.3)
        for _ in range(int(rng.integers(2, 4))):
            if min(w, h) < 1.0 * c:
                break
            out.append(_rect(x, y, cx, cy, w, h, angle) if rng.random() < 0.5
                       else _ellipse(x, y, cx, cy, w / 2, h / 2, angle))
            shrink = rng.uniform(1.0, 2.0) * c
            w, h = w - 2 * shrink, h - 2 * shrink
            cx, cy = cx + rng.uniform(-0.3, 0.3) * c, cy + rng.uniform(-0.3, 0.3) * c
    elif family == "patchwork":
        n = int(rng.integers(3, 9))
        px, py = rng.uniform(0, sx, n), rng.uniform(0, sy, n)
        d = (x[..., None] - px) ** 2 + (y[..., None] - py) ** 2
        owner = np.argmin(d, axis=-1)
        out.extend(owner == i for i in range(1, n))
    elif family == "rings":
        for _ in range(int(rng.integers(1, 3))):
            cx, cy = centre(2 * c)
            r = rng.uniform(1.5, 3.5) * c
            w = rng.uniform(0.8, 1.5) * c
            rr = np.hypot(x - cx, y - cy)
            out.append(np.abs(rr - r) <= w / 2)
    elif family == "mixed":
        out.append(_blob(rng, x, y, *centre(c), rng.uniform(1.0, 2.2) * c))
        a = _stripe_angle(rng)
        half = rng.uniform(0.25, 0.5) * math.hypot(sx, sy)
        cx, cy = centre(c)
        out.append(_segment(x, y, cx - half * math.cos(a), cy - half * math.sin(a), cx + half * math.cos(a),
                            cy + half * math.sin(a), rng.uniform(0.7, 1.3) * c))
        for _ in range(int(rng.integers(1, 3))):
            s = rng.uniform(0.8, 1.4) * c
            out.append(_rect(x, y, *centre(s), s, s))
    else:
        raise ValueError(f"unknown family {family!r}; known: {', '.join(FAMILIES)}")
    return out


def _paint(rng, masks: list[np.ndarray], k: int, shape: tuple[int, int]) -> np.ndarray:
    """Slot per pixel: the background is slot 0; each mask takes a slot other than the one most of it covers
    (so every feature differs from what it is painted on), preferring slots not used yet."""
    labels = np.zeros(shape, dtype=np.int16)
    used = [0]
    for m in masks:
        if not m.any():
            continue
        under = int(np.bincount(labels[m], minlength=k).argmax())
        choices = [s for s in range(k) if s != under]
        fresh = [s for s in choices if s not in used]
        slot = int(rng.choice(fresh if fresh and rng.random() < 0.7 else choices))
        used.append(slot)
        labels[m] = slot
    return labels


def slot_materials(rng, refs: list[int], order: np.ndarray) -> list[tuple[str, str, float, float]]:
    """Each slot's material, (name, like-reference, Young's modulus kPa, Poisson): slot i stands for reference
    ``refs[order[i]]``, as itself or (30%) a like-material 0.8-1.25x its modulus."""
    materials = []
    for slot in range(len(order)):
        name, e, nu = REFERENCES[refs[order[slot]]]
        if rng.random() < 0.3:
            materials.append((f"{name}_like{slot}", name, round(e * float(rng.uniform(0.8, 1.25)), 2), nu))
        else:
            materials.append((name, name, e, nu))
    return materials


def make_scene(seed: int, family: str | None = None) -> FamilyScene:
    """The seeded scene of ``seed`` (family ``FAMILIES[seed % len(FAMILIES)]`` unless given)."""
    rng = np.random.default_rng([seed, 15])
    family = FAMILIES[seed % len(FAMILIES)] if family is None else family
    c = float(rng.uniform(10.0, 20.0))
    nx, ny = int(rng.integers(7, 16)), int(rng.integers(6, 13))
    off = rng.uniform(0.1, 0.9, 2) * c
    sx = off[0] + nx * c + rng.uniform(0.1, 0.9) * c
    sy = off[1] + ny * c + rng.uniform(0.1, 0.9) * c
    k = int(rng.choice([2, 3, 3, 4]))
    refs = sorted(rng.choice(len(REFERENCES), k, replace=False).tolist())
    npx, npy = int(math.ceil(sx / PX_MM)), int(math.ceil(sy / PX_MM))
    x, y = np.meshgrid((np.arange(npx) + 0.5) * PX_MM, (np.arange(npy) + 0.5) * PX_MM)
    labels = _paint(rng, _masks(family, rng, x, y, sx, sy, c), k, (npy, npx))
    order = rng.permutation(k)  # which reference each slot stands for
    materials = slot_materials(rng, refs, order)
    # the memory knows every drawn reference, also one whose slot was painted over entirely (it may still be read)
    references = tuple(r[0] for r in REFERENCES if r[0] in {m[1] for m in materials})
    return FamilyScene(seed, family, c, (float(sx), float(sy)), (float(off[0]), float(off[1])), (nx, ny),
                       tuple(materials), references, labels)


@cache
def scene(seed: int) -> FamilyScene:
    """:func:`make_scene` of ``seed``, cached."""
    return make_scene(seed)
