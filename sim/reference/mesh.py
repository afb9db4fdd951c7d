"""Graded tensor meshes for the FE reference: fine and uniform where the contact is, growing geometrically away.

The contact edge sweeps the top surface from the axis out to the largest contact radius, so the radial spacing is
uniform (``h0``) over that span and grows by ``growth`` per cell beyond it; depth spacing starts at ``h0`` under
the surface and grows with depth. Material boundaries (layer interfaces, the inclusion's faces, a free side) are
grid lines, so each element holds one material (a sphere inclusion is staircased at the local spacing).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError


def graded_line(length: float, h0: float, uniform_to: float, growth: float, breaks=()) -> np.ndarray:
    """Nodes on [0, length] (m): spacing h0 up to ``uniform_to``, then multiplied by ``growth`` per cell.

    ``breaks`` (m, inside (0, length)) become nodes: the nearest node moves onto each when within a third of the
    local spacing, else a node is inserted.
    """
    if not (length > 0 and h0 > 0 and growth >= 1.0):
        raise ValidationError(f"graded_line: need length > 0, h0 > 0, growth >= 1; got {length}, {h0}, {growth}")
    xs = [0.0]
    h = h0
    while xs[-1] < length:
        if xs[-1] >= uniform_to:
            h *= growth
        xs.append(xs[-1] + h)
    x = np.array(xs)
    x[-1] = length
    if len(x) > 2 and (x[-1] - x[-2]) < 0.4 * (x[-2] - x[-3]):
        x = np.delete(x, -2)
    for b in breaks:
        if not 0.0 < b < length:
            continue
        i = int(np.argmin(np.abs(x - b)))
        local = max(x[min(i + 1, len(x) - 1)] - x[max(i - 1, 0)], 1e-300) / 2.0
        if 0 < i < len(x) - 1 and abs(x[i] - b) < local / 3.0:
            x[i] = b
        else:
            x = np.sort(np.append(x, b))
    x = np.unique(x)
    return x


@dataclass(frozen=True)
class SampleGrid:
    """The nodes of a sample's tensor mesh: radii r from the axis and depths below the top, both m, increasing."""

    r: np.ndarray
    depth: np.ndarray


def sample_grids(thickness: float, radius: float, a_max: float, h0: float, breaks_r=(), breaks_z=(), *,
                 growth: float = 1.15, depth_growth: float = 1.10) -> SampleGrid:
    """The mesh nodes for a sample ``thickness`` deep and ``radius`` wide pressed up to contact radius ``a_max``
    with surface spacing ``h0``, all m (see the module docstring)."""
    return SampleGrid(r=graded_line(radius, h0, 1.3 * a_max, growth, breaks_r),
                      depth=graded_line(thickness, h0, 0.25 * a_max, depth_growth, breaks_z))
