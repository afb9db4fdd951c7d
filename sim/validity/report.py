"""The validity table as people read it: one line per case and depth, the claims it supports, and each fidelity's
cost."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from palpate.sim.validity.cases import TIP_RADIUS
from palpate.sim.validity.table import RungCost, ValidityRow, ValidityTable


@dataclass(frozen=True)
class ClaimRule:
    """A claim to check: its label, which rows it covers, the fidelities it is about and its error bound."""

    label: str
    covers: Callable[[ValidityRow], bool]
    fidelities: tuple[str, ...]
    bound: float


#: The claims checked against the table.
CLAIMS = (
    ClaimRule("thickness >= 2 contact radii, depth <= 0.4 R", lambda r: r.family == "thickness"
              and r.a_over_h <= 0.5 and r.depth <= 0.4 * TIP_RADIUS, ("analytic", "rigid"), 0.05),
    ClaimRule("a skin over a base", lambda r: r.family == "skin", ("analytic", "rigid"), 0.10),
    ClaimRule("an on-axis lump", lambda r: r.family == "lump", ("analytic", "rigid"), 0.10),
    ClaimRule("flex, thickness >= 10 mm, depth 0.5-4 mm", lambda r: r.family == "thickness" and r.thickness >= 0.01
              and 4e-4 <= r.depth <= 4.1e-3, ("flex",), 0.10),
)


def _pct(v) -> str:
    return f"{'-':>7}" if v is None or not math.isfinite(v) else f"{100 * v:+7.1f}"


def worst(rows: list[ValidityRow], rung: str) -> float:
    """Largest |error| of ``rung`` over ``rows`` (inf if any is missing)."""
    vals = [r.error.get(rung) for r in rows]
    return max((abs(v) if v is not None else math.inf) for v in vals) if vals else math.nan


@dataclass(frozen=True)
class Claim:
    """A claim checked against the table for one fidelity.

    Attributes:
        claim: what is claimed (its label).
        fidelity: the fidelity it is about.
        rows: how many table rows it covers.
        worst: largest |relative force error| over them (inf if one is missing, NaN if there are none).
        bound: the largest error the claim allows.
        holds: there are rows and the worst is within the bound.
    """

    claim: str
    fidelity: str
    rows: int
    worst: float
    bound: float
    holds: bool


def claims(table: ValidityTable) -> list[Claim]:
    """Each claim with the worst error of each of its fidelities over its rows, and whether it holds."""
    out = []
    for rule in CLAIMS:
        rows = [r for r in table.rows if rule.covers(r)]
        for rung in rule.fidelities:
            w = worst(rows, rung)
            out.append(Claim(claim=rule.label, fidelity=rung, rows=len(rows), worst=w, bound=rule.bound,
                             holds=bool(rows) and w <= rule.bound))
    return out


def format_table(table: ValidityTable) -> str:
    """Text table: case, nu, thickness, depth, a/h, the family's feature, reference force and errors (%)."""
    rungs = table.rungs
    head = (f"{'case':24} {'nu':>5} {'h mm':>5} {'d mm':>5} {'a/h':>5} {'feat':>6} {'F ref N':>9} "
            + " ".join(f"{r + ' %':>8}" for r in rungs))
    lines = ["validity: each fidelity's force against the FE reference (robot press, 10 mm/s, 8 mm tip)", head]
    for r in table.rows:
        lines.append(f"{r.case:24} {r.poisson:5.2f} {1e3 * r.thickness:5.0f} {1e3 * r.depth:5.1f} "
                     f"{r.a_over_h:5.2f} {r.feature:6.2f} {r.reference_force:9.4g} "
                     + " ".join(f"{_pct(r.error.get(k)):>8}" for k in rungs))
    lines.append("feat: thickness / a, skin / a, lump depth / a or edge distance / a, with a = sqrt(R d)")
    lines.append("")
    lines.append("claims (worst |error| over their rows):")
    for c in claims(table):
        state = "holds" if c.holds else "FAILS"
        w = "-" if not math.isfinite(c.worst) else f"{100 * c.worst:.1f}%"
        lines.append(f"  {c.fidelity:8} {c.claim:44} {w:>7} (bound {100 * c.bound:.0f}%, {c.rows} rows): {state}")
    lines.append("")
    lines.append("cost (all cases of this run, one core):")
    for rung in rungs:
        c = table.cost.get(rung, RungCost(wall_s=0.0, sim_s=0.0))
        rt = c.realtime
        lines.append(f"  {rung:8} {c.wall_s:8.1f} s wall for {c.sim_s:7.1f} s simulated"
                     + (f" ({rt:.2f}x real time)" if rt else ""))
    for f in table.failures:
        lines.append(f"  failed: {f.fidelity} on {f.case}: {f.error[:120]}")
    return "\n".join(lines)
