"""The speed-accuracy trade as people read it: text tables, a JSON-ready report and the Pareto plot of
:mod:`palpate.sim.tradeoff`'s measurements."""

from __future__ import annotations

import numpy as np


def format_table(report: dict) -> str:
    """The measured table as text (one row per setting; times per press in ms, memory in MiB, errors in %)."""
    head = (f"{'setting':34} {'ms/press':>9} {'x RT':>7} {'MiB':>6} {'c_P%':>6} {'c_A%':>6} {'c_D%':>6} "
            f"{'n1%':>6} {'a1%':>6} {'err%':>6} {'Fref%':>7} {'LOO':>5}")
    lines = [head]
    pareto = {id(r) for r in report["pareto"]}

    def pct(v):
        return f"{100 * v:6.1f}" if v is not None and np.isfinite(v) else f"{'-':>6}"

    for r in [report["reference"]] + report["results"]:
        name = ("* " if id(r) in pareto else "  ") + r.setting.label
        if r is report["reference"]:
            name = "R " + r.setting.label
        if r.failed and not np.isfinite(r.wall_per_press):
            lines.append(f"{name:34} failed: {r.failed[:80]}")
            continue
        e = r.errors
        lines.append(
            f"{name:34} {1e3 * r.wall_per_press:9.2f} {r.realtime_factor:7.1f} {r.peak_memory / 2**20:6.2f} "
            f"{pct(e.get('c_P'))} {pct(e.get('c_A'))} {pct(e.get('c_D'))} {pct(e.get('n1'))} {pct(e.get('a1'))} "
            f"{pct(r.error)} {pct(r.law_error):>7} {r.loo_accuracy:5.2f}"
        )
    lines.append("R = reference (finest stable), * = Pareto front (time per press vs err%); err% = worst feature; "
                 "Fref% = force against the reference mechanics (RMS)")
    for key, tol in (("within_5", "5%"), ("within_1", "1%")):
        r = report[key]
        lines.append(f"cheapest within {tol} of the reference: " + (
            f"{r.setting.label} ({1e3 * r.wall_per_press:.2f} ms/press, err {100 * r.error:.2f}%)" if r else "none"))
    return "\n".join(lines)


def report_to_dict(report: dict) -> dict:
    """JSON-ready form of :func:`run_tradeoff`'s report."""
    def lab(r):
        return None if r is None else r.setting.label

    return {
        "format": "palpate-tradeoff", "version": 1,
        "reference": report["reference"].to_dict(),
        "results": [r.to_dict() for r in report["results"]],
        "pareto": [lab(r) for r in report["pareto"]],
        "cheapest_within_5pct": lab(report["within_5"]), "cheapest_within_1pct": lab(report["within_1"]),
    }


def pareto_plot(report: dict, path) -> None:
    """Write the Pareto plot (time per press vs error against the reference, log-log) as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    colours = {"analytic": "tab:green", "rigid": "tab:blue", "flex": "tab:red"}
    floor = 1e-4  # the reference's own error is 0: show it at the floor of the log axis
    for r in report["results"]:
        if r.failed or not np.isfinite(r.error):
            continue
        ax.scatter(1e3 * r.wall_per_press, max(r.error, floor), color=colours[r.setting.fidelity], s=25)
        ax.annotate(r.setting.label, (1e3 * r.wall_per_press, max(r.error, floor)), fontsize=6,
                    xytext=(3, 3), textcoords="offset points")
    front = report["pareto"]
    if front:
        ax.plot([1e3 * r.wall_per_press for r in front], [max(r.error, floor) for r in front], "k--", lw=0.8,
                label="Pareto front")
    for tol in (0.05, 0.01):
        ax.axhline(tol, color="grey", lw=0.5, ls=":")
    for fid, c in colours.items():
        ax.scatter([], [], color=c, label=fid)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time per press-and-release [ms] (one core)")
    ax.set_ylabel("error vs reference (worst of c_P, c_A, c_D, n1, a1)")
    ax.set_title(f"speed vs accuracy (reference: {report['reference'].setting.label})", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
