"""The frictionless contact of the exact sphere on a surface of boundary elements (:mod:`.surface`): cell pressures
at a ladder of indentations, each solve warm-started from the last."""

from __future__ import annotations

import math

import numpy as np

from palpate.core.errors import ValidationError
from palpate.sim.bem.surface import Surface, lattice_ij
from palpate.sim.contact.lcp import solve_contact

#: Default cell side, m.
CELL = 0.5e-3


class ContactOutgrown(ValidationError):
    """The contact reached the edge of the cells solved (a wider surface is needed)."""


def on_grid(surface: Surface) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """Each cell's (row, column) on the smallest grid that holds the surface, the grid's lower corner in cells
    from the press point, and its shape."""
    ij = lattice_ij(surface.centres, surface.cell)
    lo = ij.min(axis=0)
    return ij - lo, lo, tuple(int(v) for v in ij.max(axis=0) - lo + 1)


def solve_fields(surface: Surface, tip_radius: float, depths: np.ndarray) -> np.ndarray:
    """Cell pressures (Pa, (n, cells)) at increasing indentations ``depths`` (m). The first solve starts from the
    contact set Hertz would give (the cells whose gap exceeds half the depth); each next one from that set joined
    with the last one's stretched as a growing contact is (by sqrt of the depth ratio), which follows a contact
    that is not round."""
    r2 = np.sum(surface.centres**2, axis=1)
    if np.any(r2 >= tip_radius**2):
        raise ValidationError("bem: the surface reaches beyond the tip's radius; press shallower")
    profile = tip_radius - np.sqrt(tip_radius**2 - r2)
    fields = np.zeros((len(depths), len(r2)))
    edge = (np.sqrt(r2.max()) - surface.cell) ** 2
    at, lo, shape = on_grid(surface)
    last = np.zeros(shape, dtype=bool)
    for k, d in enumerate(depths):
        gap = d - profile
        guess = gap > 0.5 * d
        if k > 0:
            back = lattice_ij(surface.centres * math.sqrt(depths[k - 1] / d), surface.cell) - lo
            guess |= last[np.clip(back[:, 0], 0, shape[0] - 1), np.clip(back[:, 1], 0, shape[1] - 1)]
        fields[k], active = solve_contact(surface.compliance, gap, guess)
        if active.any() and np.max(r2[active]) > edge:
            raise ContactOutgrown(f"bem: the contact reached the edge of the solved surface at {d * 1e3:.2f} mm deep")
        last[at[:, 0], at[:, 1]] = active
    return fields


def solve_ladder(surface: Surface, tip_radius: float, depths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Force (N, (n,)) and sensel pressures (Pa, (n, rows * cols)) solved at increasing indentations ``depths``
    (m)."""
    fields = solve_fields(surface, tip_radius, depths)
    return fields.sum(axis=1) * surface.cell**2, fields @ surface.overlap.T
