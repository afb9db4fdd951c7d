"""``sim_vs_real.png``: simulated and real per-press parameters with the learned Gaussians (seed 000 Fig. 6.12-6.14).

One column per material; the top row is the kinesthetic plane (n1, n2), the bottom row the cutaneous plane
(a1, a2), in the units of c_P (counts, or N for a force channel). Real presses are black crosses, simulated
ones coloured dots; solid ellipses are the 1- and 2-sigma contours of the Gaussians the memory learned from the
simulated presses, dashed ones those of the real table (the same estimator, so the two read alike).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from palpate.core import files
from palpate.core.errors import ValidationError
from palpate.core.io.figures import new_figure, palette
from palpate.core.perception.param_stats import PressTable

# c_P is in counts (or N for a force channel), c_D in mm, c_A in mm^2: the laws' coefficients carry those units
_PLANES = (("n1 (c_P unit / mm^1.5)", "n2 (c_P unit)", (0, 1)), ("a1 (c_P unit / mm^3)", "a2 (c_P unit)", (3, 4)))


def _ellipse(mean: np.ndarray, cov: np.ndarray, k: float, n: int = 90) -> np.ndarray:
    """Points (n, 2) of the k-sigma contour of N(mean, cov)."""
    w, v = np.linalg.eigh(0.5 * (cov + cov.T))
    t = np.linspace(0.0, 2.0 * np.pi, n)
    circle = np.stack([np.cos(t), np.sin(t)], axis=-1) * (k * np.sqrt(np.maximum(w, 0.0)))
    return mean + circle @ v.T


def compared_materials(sim: PressTable, real: PressTable) -> list[str]:
    """The materials the figure compares: those with more than two presses in both tables."""
    return [m for m in sim.materials if m in real.materials and len(sim.of(m)) > 2 and len(real.of(m)) > 2]


def plot_sim_vs_real(path: Path, sim: PressTable, real: PressTable, ddof: int = 0) -> Path:
    """Draw :func:`sim_vs_real_figure` into ``path``; returns ``path``."""
    fig = sim_vs_real_figure(sim, real, ddof)
    with files.writing(path):
        fig.savefig(path, dpi=90)
    return Path(path)


def sim_vs_real_figure(sim: PressTable, real: PressTable, ddof: int = 0):
    """The figure for the materials of ``sim`` that ``real`` also has (:func:`compared_materials`; ValidationError
    when there is none: no empty figure).

    ``ddof``: the covariance estimator of the Gaussians (the memory's: 0 divides by n).
    """
    names = compared_materials(sim, real)
    if not names:
        raise ValidationError("sim vs real figure: no material has more than two simulated and two real presses to "
                              "compare")
    fig = new_figure(4.2 * len(names), 7.5)
    axes = fig.subplots(2, len(names), squeeze=False)
    colours = palette(len(names))
    for col, name in enumerate(names):
        colour = colours[col]
        for row, (xlab, ylab, idx) in enumerate(_PLANES):
            ax = axes[row, col]
            for rows, style, label in ((real.of(name), "--", "real"), (sim.of(name), "-", "sim")):
                pts = rows[:, list(idx)]
                if label == "real":
                    ax.plot(pts[:, 0], pts[:, 1], "x", color="black", label=f"real ({len(pts)})")
                else:
                    ax.plot(pts[:, 0], pts[:, 1], "o", color=colour, alpha=0.7, label=f"sim ({len(pts)})")
                mean, cov = pts.mean(axis=0), np.cov(pts.T, ddof=ddof)
                for k in (1.0, 2.0):
                    e = _ellipse(mean, cov, k)
                    ax.plot(e[:, 0], e[:, 1], style, color="black" if label == "real" else colour, lw=1)
            ax.set_xlabel(xlab)
            ax.set_ylabel(ylab)
            ax.grid(alpha=0.3)
            if row == 0:
                ax.set_title(name)
            ax.legend(fontsize=7, loc="best")
    fig.suptitle("Per-press parameters, simulated vs real, with 1- and 2-sigma contours of the learned Gaussians")
    fig.tight_layout()
    return fig
