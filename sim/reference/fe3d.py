"""A 3-D FE reference off the press axis: a rigid frictionless sphere pressed into a box-shaped elastic block bonded
to a rigid base, with a box-shaped inclusion beside (or under) the press point, a vertical wall between two
materials, or a top skin.

It exists because the axisymmetric reference (:mod:`.fe`) can only hold what is symmetric about the press axis,
while the contact law averages laterally varying material around the axis (sim/contact/axisymmetric.py): off the
axis that average is an approximation that nothing axisymmetric can check. Its nodal contact forces also give the
taxel image (:mod:`.fe3d_image`).

Model (quasi-static, linear elastic, small strain):

- geometry: press point at the origin, the block spans x in [-half_x, half_x], y in [-half_y, half_y], depth in
  [0, thickness]; the inclusion spans x in [near, near + length] and is centred on y = 0; a wall is the plane
  n . (x, y) = offset; a skin the top ``thickness`` of another material. Where the block is symmetric about y = 0
  (no wall, or a wall along y) only y >= 0 is meshed (u_y = 0 there), else all of it;
- mesh: a tensor-product hex mesh, uniform (spacing ``h``) across the contact and growing geometrically away, with
  grid lines on the inclusion's faces, the skin's bottom and a wall at 0 / 90 deg (each element one material; a
  wall at another angle mixes the elements it cuts, :mod:`.fe3d_solve`); trilinear bricks with selective reduced
  integration (the volumetric term at one point: no locking at nu 0.45; triquadratic bricks cost ~40x more to
  assemble and factorise here);
- boundary: the bottom bonded (u = 0), the sides free (as the scene's box), the symmetry plane u_y = 0;
- contact: the surface compliance of the top nodes within reach is condensed from the stiffness (vertical
  settlement per unit downward nodal force); at each indentation d the active set of nodes is found with f >= 0,
  settlement = d - (R - sqrt(R^2 - r^2)) (the exact sphere) where f > 0 and no penetration elsewhere (Murty's
  active-set iteration on the dense LCP); the solve is :func:`.fe3d_solve.contact_field`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.world.scene import Layer, Material
from palpate.sim.reference.mesh import graded_line


@dataclass(frozen=True)
class BoxLump:
    """A box-shaped inclusion beside the press axis, centred on the symmetry plane y = 0.

    Attributes:
        material: its material.
        near: x of its face nearest the press axis, m (>= 0: 0 puts the press over its edge; negative puts the
            press point over the lump, |near| inside it).
        length: its extent along x, m; width: along y (centred on y = 0), m.
        depth: depth of its top below the surface, m (> 0); height: its vertical extent, m.
    """

    material: Material
    near: float
    length: float
    width: float
    depth: float
    height: float

    def __post_init__(self) -> None:
        for key in ("length", "width", "depth", "height"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value > 0):
                raise ValidationError(f"BoxLump.{key} must be > 0 m, got {value!r}")
        if not math.isfinite(self.near):
            raise ValidationError(f"BoxLump.near must be finite (m), got {self.near!r}")


@dataclass(frozen=True)
class Wall:
    """A vertical plane through the whole block splitting it into two materials: the points with
    n . (x, y) > ``offset`` (n = (cos angle, sin angle)) hold ``material``, the rest the block's bulk.

    Attributes:
        material: the far side's material.
        angle: the wall normal's angle from +x, rad (0: a wall along y with ``material`` on +x).
        offset: the wall's signed distance from the press axis along n, m.
    """

    material: Material
    angle: float
    offset: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.angle) and math.isfinite(self.offset)):
            raise ValidationError(f"Wall.angle (rad) and Wall.offset (m) must be finite, got {self.angle!r}, "
                                  f"{self.offset!r}")

    @property
    def normal(self) -> tuple[float, float]:
        """(cos angle, sin angle), with components within 1e-12 of 0 set to 0 (so 90 deg is exactly (0, 1))."""
        c, s = math.cos(self.angle), math.sin(self.angle)
        return (0.0 if abs(c) < 1e-12 else c, 0.0 if abs(s) < 1e-12 else s)

    @property
    def axis_aligned(self) -> bool:
        """The wall lies along x or y (its plane can be a grid line)."""
        c, s = self.normal
        return c == 0.0 or s == 0.0


@dataclass(frozen=True)
class BoxBlock:
    """A box-shaped block on a rigid base, pressed at the centre of its top (x = y = 0).

    Materials, later ones winning where they overlap: the bulk, the wall's far side, the skin, the lump.

    Attributes:
        material: the bulk material.
        thickness: m; half_x, half_y: half its extents, m.
        lump: an optional inclusion (see :class:`BoxLump`), inside the block.
        wall: an optional vertical material boundary (see :class:`Wall`).
        skin: an optional top layer (its thickness m from the top down).
    """

    material: Material
    thickness: float
    half_x: float
    half_y: float
    lump: BoxLump | None = None
    wall: Wall | None = None
    skin: Layer | None = None

    def __post_init__(self) -> None:
        for key in ("thickness", "half_x", "half_y"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value > 0):
                raise ValidationError(f"BoxBlock.{key} must be > 0 m, got {value!r}")
        lump = self.lump
        if lump is not None and (lump.near < -self.half_x or lump.near + lump.length > self.half_x
                                 or lump.width / 2 > self.half_y or lump.depth + lump.height > self.thickness):
            raise ValidationError("BoxBlock.lump must lie inside the block")
        if self.wall is not None and abs(self.wall.offset) >= 0.9 * min(self.half_x, self.half_y):
            raise ValidationError("BoxBlock.wall.offset must lie well inside the block (|offset| < 0.9 of the "
                                  "smaller half side)")
        if self.skin is not None and not self.skin.thickness < self.thickness:
            raise ValidationError("BoxBlock.skin.thickness must be less than the block's thickness")

    @property
    def symmetric_y(self) -> bool:
        """The block is symmetric about the plane y = 0 (so a half model holds it)."""
        return self.wall is None or self.wall.normal[1] == 0.0

    def far_fraction(self, x0, x1, y0, y1, samples: int = 16) -> np.ndarray:
        """Share of each rectangle [x0, x1] x [y0, y1] (m, arrays) on the wall's far side (0 without a wall):
        exact where the rectangle lies on one side, a ``samples`` x ``samples`` midpoint count where the wall cuts
        it."""
        x0, x1, y0, y1 = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x0, x1, y0, y1)))
        out = np.zeros(x0.shape)
        if self.wall is None:
            return out
        c, s = self.wall.normal
        corners = np.stack([c * x + s * y for x in (x0, x1) for y in (y0, y1)]) - self.wall.offset
        out[np.all(corners >= 0, axis=0)] = 1.0
        cut = ~(np.all(corners >= 0, axis=0) | np.all(corners <= 0, axis=0))
        if np.any(cut):
            t = (np.arange(samples) + 0.5) / samples
            px = x0[cut][:, None, None] + (x1 - x0)[cut][:, None, None] * t[None, :, None]
            py = y0[cut][:, None, None] + (y1 - y0)[cut][:, None, None] * t[None, None, :]
            out[cut] = np.mean(c * px + s * py > self.wall.offset, axis=(1, 2))
        return out

    def materials_at(self, x: np.ndarray, y: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(Young Pa, Poisson) at points (m; depth below the top)."""
        x, y, depth = (np.asarray(v, dtype=float) for v in (x, y, depth))
        young = np.full(x.shape, self.material.young)
        poisson = np.full(x.shape, self.material.poisson)
        regions = []
        if self.wall is not None:
            c, s = self.wall.normal
            regions.append((c * x + s * y > self.wall.offset, self.wall.material))
        if self.skin is not None:
            regions.append((depth < self.skin.thickness, self.skin.material))
        lump = self.lump
        if lump is not None:
            regions.append((((x > lump.near) & (x < lump.near + lump.length) & (np.abs(y) < lump.width / 2)
                             & (depth > lump.depth) & (depth < lump.depth + lump.height)), lump.material))
        for inside, material in regions:
            young[inside] = material.young
            poisson[inside] = material.poisson
        return young, poisson


@dataclass(frozen=True)
class TensorGrid:
    """Grid lines of the tensor-product mesh, m: x and y from the press axis, depth below the top."""

    x: np.ndarray
    y: np.ndarray
    depth: np.ndarray


def _flank(x: np.ndarray, at: float, h: float) -> np.ndarray:
    """Grid lines ``x`` with lines added h/4 either side of the line ``at`` (which must be one), nodes closer than
    h/5 to an added line dropped (never ``at``)."""
    for side in (at - h / 4, at + h / 4):
        if x[0] < side < x[-1]:
            x = np.unique(np.append(x[(np.abs(x - side) >= h / 5) | np.isclose(x, at, rtol=0, atol=1e-12)], side))
    return x


def block_grids(block: BoxBlock, a_max: float, h: float, growth: float = 1.3, half: bool = True, *,
                depth_growth: float | None = None, depth_uniform: float = 0.25) -> TensorGrid:
    """Grid lines: spacing ``h`` out to 1.3 a_max from the press axis (and ``depth_uniform`` a_max deep), growing
    by ``growth`` per cell beyond (with depth by ``depth_growth``, None: ``growth``); the lump's faces, an
    axis-aligned wall (with lines h/4 either side) and the skin's bottom are grid lines. ``half``: y from 0 only
    (the half model), else across the whole block."""
    bx, by, bz = [], [], []
    lump = block.lump
    if lump is not None:
        bx += [lump.near, lump.near + lump.length]
        by += [lump.width / 2, -lump.width / 2]
        bz += [lump.depth, lump.depth + lump.height]
    wall = block.wall
    at = None
    if wall is not None and wall.axis_aligned:
        c, s = wall.normal
        at = wall.offset / (c if c != 0.0 else s)
        (bx if c != 0.0 else by).append(at)
    if block.skin is not None:
        bz.append(block.skin.thickness)
    uniform = 1.3 * a_max

    def symmetric(half_side: float, breaks: list[float]) -> np.ndarray:
        right = graded_line(half_side, h, uniform, growth, [b for b in breaks if b > 0])
        left = graded_line(half_side, h, uniform, growth, [-b for b in breaks if b < 0])
        return np.unique(np.concatenate([-left[::-1], right]))

    x = symmetric(block.half_x, bx)
    y = graded_line(block.half_y, h, uniform, growth, [b for b in by if b > 0]) if half else symmetric(
        block.half_y, by)
    if at is not None:
        # the wall node's tributary strip narrows to h/4, so the pressure's jump at the wall is not smeared over a
        # whole cell in the image
        if wall.normal[0] != 0.0:
            x = _flank(x, at, h)
        else:
            y = _flank(y, at, h)
    z = graded_line(block.thickness, h, depth_uniform * a_max, growth if depth_growth is None else depth_growth, bz)
    return TensorGrid(x=x, y=y, depth=z)
