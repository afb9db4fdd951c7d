"""Influence coefficients of the surface grid: the settlement of each cell's centre under a unit uniform pressure
on another cell, on a laterally uniform layer stack bonded to a rigid base.

The stack's surface compliance in the Fourier domain is G(q) = 2 H(q) / (E*_top q) (:mod:`palpate.sim.contact.
layered`, exact for any stack). It is split into the half-space of the top material (H = 1), whose coefficient for a
square cell has Love's closed form, and the remainder 2 (H - 1) / (E*_top q), which decays beyond q ~ 1 / (top layer
thickness) and is therefore smooth in space: it is evaluated by a Hankel transform with the cell as a disc of the
same area, tabulated in the distance between the cells and interpolated.

All coefficients are per unit E*_top (m^3 / N times E*_top): the caller divides by the stack's top modulus.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.special import j0, j1

from palpate.core.errors import ValidationError
from palpate.sim.contact.layered import surface_kernel


@dataclass(frozen=True)
class Stack:
    """A laterally uniform layer stack on a bonded rigid base, top first: thickness (m), Young (Pa), Poisson.

    The last layer reaches the base. Used as a cache key, so the values are plain tuples of floats.
    """

    thickness: tuple[float, ...]
    young: tuple[float, ...]
    poisson: tuple[float, ...]

    def __post_init__(self) -> None:
        n = len(self.thickness)
        if not (n and len(self.young) == n and len(self.poisson) == n):
            raise ValidationError("Stack: one thickness, Young modulus and Poisson ratio per layer")
        for h, e, nu in zip(self.thickness, self.young, self.poisson, strict=True):
            if not (math.isfinite(h) and h > 0 and math.isfinite(e) and e > 0 and 0.0 <= nu < 0.5):
                raise ValidationError(f"Stack: a layer needs thickness > 0 m, Young > 0 Pa and 0 <= nu < 0.5; got "
                                      f"{h!r}, {e!r}, {nu!r}")

    @property
    def top_modulus(self) -> float:
        """E* = E / (1 - nu^2) of the top layer, Pa."""
        return self.young[0] / (1.0 - self.poisson[0] ** 2)

    def scaled(self) -> Stack:
        """The same stack with the top modulus 1: stacks that differ only by a common factor of their moduli share
        one set of coefficients."""
        e0 = self.young[0]
        return Stack(self.thickness, tuple(e / e0 for e in self.young), self.poisson)


def love_rectangle(dx: np.ndarray, dy: np.ndarray, half: float) -> np.ndarray:
    """Integral of 1 / distance over the square of side 2 ``half`` centred at offset (dx, dy) from the point, m.

    A half-space's settlement under unit uniform pressure on that square is this over (pi E*) (Love 1929).
    """
    def f(x, y):
        r = np.hypot(x, y)
        # x ln(y + r) + y ln(x + r): each log's argument vanishes only where its factor does
        t1 = np.where(x != 0, x * np.log(np.where(x != 0, y + r, 1.0)), 0.0)
        t2 = np.where(y != 0, y * np.log(np.where(y != 0, x + r, 1.0)), 0.0)
        return t1 + t2

    x1, x2 = dx - half, dx + half
    y1, y2 = dy - half, dy + half
    return f(x2, y2) - f(x1, y2) - f(x2, y1) + f(x1, y1)


def _correction_table(stack: Stack, cell: float, r_max: float) -> tuple[np.ndarray, np.ndarray]:
    """The finite-stack remainder of a cell's coefficient against distance, per unit E*_top: (r, value), m and
    m^3/N x Pa."""
    scaled = stack.scaled()
    h_top = scaled.thickness[0]
    depth = sum(scaled.thickness)
    # H - 1 falls as exp(-2 q h) under a homogeneous top: past q h_top ~ 12 it is below 1e-10 of the rest
    q_max = 12.0 / min(h_top, depth)
    rho = cell / math.sqrt(math.pi)
    q_max = min(q_max, 60.0 / rho)
    dq = min(math.pi / (8.0 * r_max), q_max / 400.0)
    q = (np.arange(int(math.ceil(q_max / dq))) + 0.5) * dq
    h = surface_kernel(q, np.array(scaled.thickness), np.array(scaled.young), np.array(scaled.poisson))
    qr = q * rho
    disc = 2.0 * j1(qr) / qr
    r = np.linspace(0.0, r_max, int(math.ceil(r_max / (cell / 8.0))) + 1)
    # u(r) = A / (2 pi) int G_rest(q) D(q) J0(q r) q dq with G_rest = 2 (H - 1) / q (E* = 1), A = cell^2
    weights = (h - 1.0) * disc * dq
    values = cell * cell / math.pi * (j0(np.outer(r, q)) @ weights)
    return r, values


@lru_cache(maxsize=64)
def _cached_table(stack: Stack, cell: float, r_max: float) -> tuple[np.ndarray, np.ndarray]:
    return _correction_table(stack, cell, r_max)


def influence(stack: Stack, cell: float, dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    """Settlement at offsets (dx, dy) (m, any shape) from a square cell of side ``cell`` (m) under unit uniform
    pressure on it, times the stack's top E* (so in m): Love's half-space part plus the stack's remainder.

    The remainder's table is cached per (stack scaled to a unit top modulus, cell, reach), so presses on the same
    stack share it.
    """
    dx, dy = np.asarray(dx, dtype=float), np.asarray(dy, dtype=float)
    if not (cell > 0 and math.isfinite(cell)):
        raise ValidationError(f"influence: cell must be > 0 m, got {cell!r}")
    dist = np.hypot(dx, dy)
    # tabulate to a rounded reach so nearby windows share one table
    r_max = max(cell, float(dist.max(initial=0.0)))
    r_max = _round_reach(r_max)
    r, values = _cached_table(stack.scaled(), float(cell), r_max)
    return love_rectangle(dx, dy, cell / 2.0) / math.pi + np.interp(dist, r, values)


def _round_reach(r: float) -> float:
    """``r`` rounded up to 1 mm (tables are keyed on it)."""
    return math.ceil(r * 1000.0 - 1e-9) / 1000.0
