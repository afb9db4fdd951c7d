"""The sim-to-real report of a run: the simulated training presses against a real per-press table, per material.

For every material in both, and for each of n1, n2, Phi_N, a1, a2, Phi_A: real and simulated mean, coefficient of
variation and share of negative values (:func:`~palpate.core.perception.param_stats.column_stats`), and the
distance between the two distributions: the energy distance of the standardised [n1, n2, a1, a2] rows
(:func:`~palpate.core.perception.param_stats.material_distance`; 0 = the same distribution; two samples of 10 from
one distribution typically give ~0.1-0.3). It also says, per material, how far the simulated CVs of n1 and a1 are
from the real ones (ratio) and how many more presses of 10 have n2 < 0 (the realism targets).

One session of 10 presses per material says little about the simulator; with ``[realism] predictive_sessions`` the
run adds the predictive check (:mod:`palpate.core.session.predictive`): per material a verdict on whether the real
table looks like one more of that many fresh simulated sessions (``predictive_check``; null when off).
"""

from __future__ import annotations

from pathlib import Path

from palpate.core.perception.param_stats import STAT_COLUMNS, ColumnStats, PressTable, column_stats, material_distance
from palpate.core.perception.realism_targets import negative_difference_per_10

DISTANCE = ("energy distance (Szekely & Rizzo) between the simulated and real [n1, n2, a1, a2] rows of one "
            "material, each column divided by the real table's standard deviation; 0 = same distribution")


def _stats(s: ColumnStats) -> dict:
    return {"mean": s.mean, "sd": s.sd, "cv": s.cv, "negative_fraction": s.negative_fraction, "n": s.n}


def sim_to_real_summary(sim: PressTable, real: PressTable, real_file: str | Path) -> dict:
    """The report as summary.json holds it (``materials``: one entry per material found in both tables)."""
    out: dict = {"real_table": str(real_file), "distance": DISTANCE, "materials": {}, "predictive_check": None}
    for name in sim.materials:
        if name not in real.materials:
            continue
        s, r = sim.of(name), real.of(name)
        if len(s) < 2 or len(r) < 2:
            continue
        cols = {c: {"real": _stats(column_stats(r[:, j])), "sim": _stats(column_stats(s[:, j]))}
                for j, c in enumerate(STAT_COLUMNS)}
        entry = {"presses": {"sim": len(s), "real": len(r)}, "columns": cols,
                 "energy_distance": material_distance(s, r)}
        for c in ("n1", "a1"):
            sim_cv, real_cv = cols[c]["sim"]["cv"], cols[c]["real"]["cv"]
            entry[f"cv_ratio_{c}"] = None if not (sim_cv and real_cv) else sim_cv / real_cv
        entry["negative_n2_per_10_difference"] = negative_difference_per_10(s[:, 1], r[:, 1])
        out["materials"][name] = entry
    return out


def _num(v, fmt: str) -> str:
    return "n/a" if v is None else format(v, fmt)


def format_sim_to_real(doc: dict) -> str:
    """The report as printed: per material, real / simulated mean, CV and negative share of each column."""
    lines = [f"Sim-to-real (training presses vs {doc['real_table']}): real / sim"]
    lines.append(f"{'':14}{'column':>8}{'mean':>22}{'CV':>16}{'negative':>14}")
    for name, m in doc["materials"].items():
        for j, c in enumerate(STAT_COLUMNS):
            r, s = m["columns"][c]["real"], m["columns"][c]["sim"]
            lines.append(f"{name if j == 0 else '':14}{c:>8}{_num(r['mean'], '.4g'):>11} /{_num(s['mean'], '.4g'):>9}"
                         f"{_num(r['cv'], '.2f'):>8} /{_num(s['cv'], '.2f'):>6}"
                         f"{r['negative_fraction']:>7.1f} /{s['negative_fraction']:>5.1f}")
        lines.append(f"{'':14}energy distance {m['energy_distance']:.2f}; CV ratio sim/real n1 "
                     f"{_num(m['cv_ratio_n1'], '.2f')}, a1 {_num(m['cv_ratio_a1'], '.2f')}; "
                     f"n2 < 0: {m['negative_n2_per_10_difference']:+.1f} per 10 presses")
    lines.append(format_predictive(doc.get("predictive_check")))
    return "\n".join(lines)


def format_predictive(check: dict | None) -> str:
    """The predictive check's verdict per material, as printed (one line when it was not run)."""
    if check is None:
        return "Predictive check: not run ([realism] predictive_sessions = S >= 100 runs it on S fresh sessions)"
    lines = [f"Predictive check (real table vs {check['sessions']} fresh simulated sessions): "
             f"{'PASS' if check['passed'] else 'FAIL'}, {check['band_misses']} decisive band(s) missed (1 allowed)"]
    for name, m in check["materials"].items():
        c, e = m["c2st"], m["energy"]
        out = [k for k, b in m["bands"].items() if b["decisive"] and not b["inside"]]
        lines.append(f"  {name:<12} {'pass' if m['passed'] else 'FAIL'}: classifier accuracy {c['accuracy']:.2f} "
                     f"(max {c['max']:.2f}), energy distance {e['real']:.2f} (sessions' max {e['sessions_max']:.2f}, "
                     f"p {e['p']:.3f}), bands missed: {', '.join(out) or 'none'}")
    dropped = sum(check.get("dropped_presses", {}).values())
    if dropped:
        lines.append(f"  {dropped} simulated press(es) dropped (fit failed)")
    return "\n".join(lines)
