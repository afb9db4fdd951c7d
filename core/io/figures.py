"""Figures of a run (PNG), drawn headless with matplotlib's Agg canvas (and pyvista off-screen for 3-D).

- ``training_series.png``: c_P, c_A, c_D over time for the training presses, one column per material (seed 000
  Fig. 6.8-6.10);
- ``interaction_profiles.png``: (c_A, c_D, c_P) of every training press per material (Fig. 6.11);
- ``<object>_map.png``: the map as a probability image, each material's colour weighted by its probability
  (Fig. 6.22-6.26), mid-way, final, and after post-processing, with the pressed cells outlined (the untouched map at
  k = 0, one uniform colour, is left out);
- ``<object>_entropy.png``: the entropy map before and after post-processing;
- ``exploration_progress.png``: mean entropy and accuracy of explored cells against presses, one line per object;
- voxel maps: ``<object>_columns.png`` (seed 001 Fig. 4 column view) and ``<object>_voxels_3d.png`` (pyvista).

Figures are a run's slowest stage after the physics, so they are drawn the cheap way: a bare ``Figure`` on an Agg
canvas (no pyplot state), fixed margins instead of a layout engine, a few explicit ticks, one artist per series
rather than one per press or cell, and fast PNG compression.

Materials are told apart by the Okabe-Ito colours (blue, orange, bluish green, ...), which readers with any common
colour-vision deficiency still tell apart; every axis says its unit. Each ``plot_*`` function draws its ``*_figure``
(the matplotlib Figure, which tests inspect) into a file.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from palpate.core import files
from palpate.core.errors import ValidationError
from palpate.core.mapping.geometry import MapGeometry
from palpate.core.mapping.probability import entropy
from palpate.core.mapping.snapshot import MapSnapshot

if TYPE_CHECKING:  # the figure process need not import the perception stack
    from palpate.core.perception.press import PressResult

DPI = 100
PNG = {"compress_level": 1}  # zlib level 1: a few times faster than the default 6, files ~1.3x larger
# Okabe & Ito's colour-blind-safe palette (sRGB 0-255), most distinct pairs first: blue/orange is the pair that
# stays apart under protanopia, deuteranopia and tritanopia.
COLOUR_NAMES = ("blue", "orange", "bluish green", "reddish purple", "sky blue", "vermillion", "yellow")
_PALETTE = np.array([[0, 114, 178], [230, 159, 0], [0, 158, 115], [204, 121, 167], [86, 180, 233], [213, 94, 0],
                     [240, 228, 66]], float) / 255.0


@dataclass(frozen=True)
class ProgressSeries:
    """One object's exploration progress: press numbers, mean map entropy and explored-cell accuracy after each
    press (NaN where there is no truth)."""

    name: str
    k: np.ndarray
    mean_entropy: np.ndarray
    accuracy_explored: np.ndarray


def new_figure(width: float, height: float):
    """A bare figure (inches) on an Agg canvas: no pyplot, so no global figure registry and no GUI backend."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def warm_up() -> None:
    """Import matplotlib and draw a tiny figure with text (loads the fonts): what the first figure of a process
    would otherwise pay. A background drawer calls it while the run still trains."""
    import io

    fig = new_figure(1, 1)
    ax = fig.add_subplot(projection="3d")
    ax.set_title("x")
    fig.savefig(io.BytesIO(), format="png", dpi=20)


def _save(fig, path: Path) -> Path:
    with files.writing(path):
        fig.savefig(path, dpi=DPI, pil_kwargs=PNG)
    return path


def _nice_ticks(lo: float, hi: float, n: int = 4) -> np.ndarray:
    """At most ``n`` + 1 round tick positions within [lo, hi] (computed once instead of by a tick locator)."""
    from matplotlib.ticker import MaxNLocator

    ticks = MaxNLocator(nbins=n).tick_values(lo, hi)
    return ticks[(ticks >= lo - 1e-9 * abs(hi - lo)) & (ticks <= hi + 1e-9 * abs(hi - lo))]


def palette(m: int) -> np.ndarray:
    """(m, 3) display colour of each material (:data:`COLOUR_NAMES`), grey past the seventh."""
    if m <= len(_PALETTE):
        return _PALETTE[:m]
    return np.vstack([_PALETTE, np.full((m - len(_PALETTE), 3), 0.5)])


def rgb_image(probabilities: np.ndarray) -> np.ndarray:
    """(…, M) probabilities -> (…, 3) RGB in [0, 1]: each material's :func:`palette` colour weighted by its
    probability (a certain cell shows its material's colour, an unsure one a mix)."""
    p = np.asarray(probabilities, dtype=float)
    return np.clip(p @ palette(p.shape[-1]), 0.0, 1.0)


def colour_legend(materials: Sequence[str]) -> str:
    """'blue = A · orange = B · ...': which colour shows which material's probability."""
    return " · ".join(f"{c} = {m}" for c, m in zip(COLOUR_NAMES, materials, strict=False))


def plot_training_series(path: Path, training: Mapping[str, Sequence[PressResult]]) -> Path:
    """Draw :func:`training_series_figure` into ``path``."""
    return _save(training_series_figure(training), path)


def training_series_figure(training: Mapping[str, Sequence[PressResult]]):
    """c_P, c_A (mm^2), c_D (mm) against time for every training press: one panel per feature, the materials one
    after the other on a shared scale (so their stiffness compares at a glance), presses laid end to end."""
    fig = new_figure(12, 7)
    axes = fig.subplots(3, 1, sharex=True)
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.08, top=0.9, hspace=0.08)
    colours = palette(len(training))
    t_off = 0.0
    for j, (name, results) in enumerate(training.items()):
        # One line per feature and material, NaN between presses: one artist instead of one per press.
        ts, cols = [], [[], [], []]
        t_start = t_off
        for res in results:
            pr = res.press
            if pr is None:
                continue
            t = pr.t - pr.t[0] + t_off
            ts += [t, [np.nan]]
            for c, v in zip(cols, (pr.c_P, pr.c_A * 1e6, pr.c_D * 1e3), strict=True):
                c += [v, [np.nan]]
            t_off = t[-1] + 0.2
        if ts:
            for ax, c in zip(axes, cols, strict=True):
                ax.plot(np.concatenate(ts), np.concatenate(c), color=colours[j], lw=1, label=name)
        axes[0].text((t_start + t_off) / 2, 1.02, name, transform=axes[0].get_xaxis_transform(), ha="center",
                     va="bottom", color=colours[j], fontsize=10)
        t_off += 0.8
        if j < len(training) - 1:
            for ax in axes:
                ax.axvline(t_off - 0.5, color="0.8", lw=0.8)
    for ax, label in zip(axes, ["c_P (counts)", "c_A (mm²)", "c_D (mm)"], strict=True):
        ax.set_ylabel(label)
    axes[2].set_xlabel("press phases of the training presses, laid end to end (s)")
    fig.suptitle("Contact features during the training presses (press phase of each press)", fontsize=11)
    return fig


def plot_interaction_profiles(path: Path, training: Mapping[str, Sequence[PressResult]]) -> Path:
    """Draw :func:`interaction_profiles_figure` into ``path``."""
    return _save(interaction_profiles_figure(training), path)


def interaction_profiles_figure(training: Mapping[str, Sequence[PressResult]]):
    """3-D scatter of (c_A, c_D, c_P) per material: the contact-interaction signature."""
    fig = new_figure(7, 5.5)
    ax = fig.add_subplot(projection="3d")
    fig.subplots_adjust(left=0.0, right=0.95, bottom=0.02, top=0.93)
    colours = palette(len(training))
    for j, (name, results) in enumerate(training.items()):
        presses = [r.press for r in results if r.press is not None]
        xs = np.concatenate([p.c_A * 1e6 for p in presses] or [np.zeros(0)])
        ys = np.concatenate([p.c_D * 1e3 for p in presses] or [np.zeros(0)])
        zs = np.concatenate([p.c_P for p in presses] or [np.zeros(0)])
        ax.scatter(xs, ys, zs, s=6, color=colours[j], label=name, depthshade=False)
    ax.set_xlabel("c_A (mm²)")
    ax.set_ylabel("c_D (mm)")
    ax.set_zlabel("c_P (counts)")
    ax.legend(loc="upper left")
    ax.set_title("Contact-interaction profile per reference material")
    return fig


def _extent(geometry: MapGeometry, shape: tuple[int, int]) -> list[float]:
    """imshow extent in cm of a (ny, nx) image of the map."""
    (x0, y0), c = geometry.origin[:2], geometry.cell_size
    ny, nx = shape
    return [x0 * 100, (x0 + nx * c) * 100, y0 * 100, (y0 + ny * c) * 100]


def _panel_size(aspect: float, width: float, margins: float) -> tuple[float, float]:
    """(panel width, figure height) in inches for map panels of ``aspect`` = nx / ny: wide maps get wider panels
    (up to 1.6x), tall ones a taller figure (images of at most 5 in)."""
    panel_w = width * min(1.6, max(1.0, aspect))
    image_h = min(5.0, max(1.2, 0.78 * panel_w / aspect))
    return panel_w, image_h + margins


def _map_axes(fig, n: int, height: float, right: float = 0.2):
    """``n`` map panels side by side with fixed margins (inches): room for a title, tick labels and axis labels."""
    width = fig.get_figwidth()
    # Panels share both axes: ticks are worked out once, and only the first panel labels y.
    axes = fig.subplots(1, n, squeeze=False, sharex=True, sharey=True)[0]
    fig.subplots_adjust(left=0.7 / width, right=1 - right / width, bottom=0.55 / height, top=1 - 0.75 / height,
                        wspace=0.12)
    for ax in axes[1:]:
        ax.tick_params(labelleft=False)
    return axes


def _map_panel(ax, img: np.ndarray, ext: list[float], title: str, **kw) -> object:
    im = ax.imshow(img, origin="lower", extent=ext, interpolation="nearest", **kw)
    ax.set_xticks(_nice_ticks(ext[0], ext[1], 3))
    ax.set_yticks(_nice_ticks(ext[2], ext[3], 3))
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("x (cm)")
    return im


def _outline_cells(ax, explored: np.ndarray, ext: list[float], cell_cm: float) -> None:
    """White outlines of the pressed cells, as one line collection."""
    from matplotlib.collections import PolyCollection

    cells = np.argwhere(explored)
    if not len(cells):
        return
    x = ext[0] + cells[:, 1] * cell_cm
    y = ext[2] + cells[:, 0] * cell_cm
    verts = np.stack([np.stack([x, y], 1), np.stack([x + cell_cm, y], 1), np.stack([x + cell_cm, y + cell_cm], 1),
                      np.stack([x, y + cell_cm], 1)], axis=1)
    ax.add_collection(PolyCollection(verts, facecolors="none", edgecolors="white", linewidths=1.2))


def plot_map_snapshots(path: Path, name: str, snapshots: Sequence[MapSnapshot], geometry: MapGeometry,
                       truth: np.ndarray | None = None) -> Path:
    """Draw :func:`map_snapshots_figure` into ``path``."""
    return _save(map_snapshots_figure(name, snapshots, geometry, truth), path)


def map_snapshots_figure(name: str, snapshots: Sequence[MapSnapshot], geometry: MapGeometry,
                         truth: np.ndarray | None = None):
    """Probability maps mid-way, final and post-processed (2-D grid), plus the ground truth. A snapshot with no
    pressed cell (the map at k = 0: one uniform colour) is left out, unless nothing else would be drawn."""
    materials = list(geometry.materials)
    shown = [s for s in snapshots if np.asarray(s.explored).any()]
    if not shown and truth is None:
        shown = list(snapshots[-1:])
    panels: list[MapSnapshot | None] = shown + ([None] if truth is not None else [])
    if not panels:
        raise ValidationError(f"{name}: no map snapshot and no ground truth to draw")
    ny, nx = (truth.shape if not snapshots else snapshots[0].probabilities.shape)[:2]
    panel_w, height = _panel_size(nx / ny, 2.6, 1.3)
    fig = new_figure(panel_w * len(panels) + 0.9, height)
    axes = _map_axes(fig, len(panels), height)
    cell_cm = geometry.cell_size * 100
    for ax, snap in zip(axes, panels, strict=True):
        if snap is None:  # the ground-truth panel
            p = np.zeros(truth.shape + (len(materials),))
            valid = truth >= 0
            p[valid] = np.eye(len(materials))[truth[valid]]
            img, explored, label = rgb_image(p), None, "ground truth"
        else:
            img, explored, label = rgb_image(snap.probabilities), snap.explored, snap.label
        ext = _extent(geometry, img.shape[:2])
        _map_panel(ax, img, ext, label)
        if explored is not None and label != "post-processed":
            _outline_cells(ax, explored, ext, cell_cm)
    axes[0].set_ylabel("y (cm)")
    fig.suptitle(f"{name}: P(material) as colour ({colour_legend(materials)}); pressed cells outlined", fontsize=10)
    return fig


def entropy_unit(base: float) -> str:
    """The unit of an entropy in logarithms of ``base``: bit (2), nat (e), hartley (10), else "base-b unit"."""
    for b, unit in ((2.0, "bit"), (float(np.e), "nat"), (10.0, "hartley")):
        if abs(base - b) < 1e-12:
            return unit
    return f"base-{base:g} unit"


def entropy_label(base: float) -> str:
    """Colour-bar label of an entropy map: the unit follows the logarithm's base, the colour scale is linear."""
    return f"entropy H ({entropy_unit(base)}: base-{base:g} logarithm; linear colour scale)"


def plot_entropy(path: Path, name: str, before: np.ndarray, after: np.ndarray, geometry: MapGeometry) -> Path:
    """Draw :func:`entropy_figure` into ``path``."""
    return _save(entropy_figure(name, before, after, geometry), path)


def entropy_figure(name: str, before: np.ndarray, after: np.ndarray, geometry: MapGeometry):
    """Entropy per cell (in the map's entropy base) before and after post-processing, on one linear colour scale
    from 0 (certain) to the maximum for the number of materials (uniform)."""
    base = geometry.entropy_base
    hb, ha = entropy(before, base=base), entropy(after, base=base)
    vmax = float(np.log(before.shape[-1]) / np.log(base))
    ny, nx = hb.shape
    panel_w, height = _panel_size(nx / ny, 3.0, 1.5)
    fig = new_figure(2 * panel_w + 2.3, height)
    axes = _map_axes(fig, 2, height, right=1.6)
    for ax, h, title in zip(axes, (hb, ha), ("final map", "after post-processing"), strict=True):
        im = _map_panel(ax, h, _extent(geometry, h.shape), f"{title}\nmean H = {h.mean():.3f}", vmin=0, vmax=vmax,
                        cmap="magma")
    axes[0].set_ylabel("y (cm)")
    width = fig.get_figwidth()
    cax = fig.add_axes((1 - 1.35 / width, 0.55 / height, 0.15 / width, 1 - 1.3 / height), label="<colorbar>")
    fig.colorbar(im, cax=cax).set_label(entropy_label(base), fontsize=8)
    fig.suptitle(f"{name}: map entropy (0 = certain, {vmax:.3f} {entropy_unit(base)} = all materials equally "
                 "likely)", fontsize=10)
    return fig


_STYLES = (("-", "o"), ("--", "s"), (":", "^"), ("-.", "D"), ((0, (5, 1, 1, 1)), "v"), ((0, (1, 1)), "P"))


def plot_progress(path: Path, series: Sequence[ProgressSeries], base: float = 10.0) -> Path:
    """Draw :func:`progress_figure` into ``path``."""
    return _save(progress_figure(series, base), path)


def progress_figure(series: Sequence[ProgressSeries], base: float = 10.0):
    """Mean entropy (logarithms of ``base``) and accuracy of the explored cells after each press, one line per object.

    Objects often follow the same curve (same layout, same policy), so each gets its own line style and hollow
    marker, and earlier lines are drawn wider underneath later ones: a line exactly under another stays visible.
    """
    fig = new_figure(10, 3.8)
    a1, a2 = fig.subplots(1, 2)
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.14, top=0.86, wspace=0.25)
    n = len(series)
    for i, s in enumerate(series):
        ls, marker = _STYLES[i % len(_STYLES)]
        style = {"ls": ls, "marker": marker, "ms": 4 + 2.5 * (n - 1 - i), "mfc": "none", "lw": 1.2 + 1.5 * (n - 1 - i),
                 "alpha": 0.9, "label": s.name, "zorder": 2 + i}
        a1.plot(s.k, s.mean_entropy, **style)
        a2.plot(s.k, s.accuracy_explored, **style)
    a1.set_xlabel("press k (presses)")
    a1.set_ylabel(f"mean entropy of the map ({entropy_unit(base)})")
    a2.set_xlabel("press k (presses)")
    a2.set_ylabel("accuracy of explored cells (fraction)")
    a2.set_ylim(-0.05, 1.05)
    a1.legend(fontsize=8)
    fig.suptitle("Exploration progress per object (identical curves overlap: wider lines are underneath)",
                 fontsize=10)
    return fig


def plot_voxel_columns(path: Path, name: str, grid, post, materials: list[str]) -> Path:
    """Draw :func:`voxel_columns_figure` into ``path``."""
    return _save(voxel_columns_figure(name, grid, post, materials), path)


def voxel_columns_figure(name: str, grid, post, materials: list[str]):
    """Seed 001 Fig. 4: explored columns as stacks of coloured voxels, before and after post-processing.
    ValidationError when no column was explored (the figure would be empty)."""
    explored_cols = np.argwhere(np.asarray(grid.explored).any(axis=2))
    if not len(explored_cols):
        raise ValidationError(f"{name}: no explored voxel column to draw")
    cols = explored_cols[: min(len(explored_cols), 24)]
    width = max(6.0, 0.45 * len(cols) + 2)
    fig = new_figure(width, 5.4)
    axes = fig.subplots(2, 1, squeeze=False)
    fig.subplots_adjust(left=0.9 / width, right=1 - 0.2 / width, bottom=0.2, top=0.88, hspace=0.9)
    for ax, g, title in ((axes[0, 0], grid, "explored"), (axes[1, 0], post, "after post-processing")):
        strip = np.stack([rgb_image(g.probabilities[ix, iy]) for ix, iy in cols], axis=1)  # (nz, ncols, 3)
        ax.imshow(strip, aspect="auto", interpolation="nearest")
        ax.set_xticks(range(len(cols)), [f"{ix},{iy}" for ix, iy in cols], rotation=90, fontsize=7)
        ax.set_xlabel("explored column (cell index ix,iy)", fontsize=8)
        ax.set_ylabel("voxel layer\n(layer index, 0 = surface)")
        ax.set_title(f"{name}: voxel columns (cell ix,iy), {title}", fontsize=10)
    fig.suptitle(f"P(material) as colour: {colour_legend(materials)}", fontsize=9)
    return fig


def render_voxels_3d(path: Path, grid, cell_size: float, name: str = "", materials: Sequence[str] = ()) -> Path | None:
    """Off-screen pyvista render of the explored voxels coloured by P(material), with a title, axes in cm and a
    legend of the material colours (None if pyvista is missing)."""
    try:
        import pyvista as pv
        from vtkmodules.vtkCommonCore import vtkLogger
    except ImportError:
        return None
    # Headless, VTK tries an X display first and logs a warning before it falls back to EGL or OSMesa; only
    # errors are worth showing for an off-screen picture.
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    probs = np.asarray(grid.probabilities)
    explored = np.asarray(grid.explored)
    nx, ny, nz = explored.shape
    img = pv.ImageData(dimensions=(nx + 1, ny + 1, nz + 1), spacing=(cell_size * 100,) * 3)
    # voxel layer 0 is the surface; flip z so the picture is upright.
    colors = (rgb_image(probs[:, :, ::-1]) * 255).astype(np.uint8)
    img.cell_data["rgb"] = colors.reshape(-1, 3, order="F")
    img.cell_data["explored"] = explored[:, :, ::-1].reshape(-1, order="F").astype(np.uint8)
    shown = img.threshold(0.5, scalars="explored")
    plotter = pv.Plotter(off_screen=True, window_size=(900, 700))
    plotter.set_background("white")
    if shown.n_cells:
        plotter.add_mesh(shown, scalars="rgb", rgb=True, show_edges=True)
    plotter.add_mesh(img.outline(), color="black")
    plotter.show_bounds(xtitle="x (cm)", ytitle="y (cm)", ztitle="height (cm, top = surface)", color="black",
                        font_size=10, location="outer")
    materials = list(materials) or [f"material {i + 1}" for i in range(probs.shape[-1])]
    plotter.add_legend([[f"P({m})", tuple(c)] for m, c in zip(materials, palette(len(materials)), strict=True)],
                       bcolor="white", face="rectangle", size=(0.22, 0.05 + 0.04 * len(materials)))
    plotter.add_text(f"{name}: explored voxels after post-processing, coloured by P(material)".lstrip(": "),
                     font_size=11, color="black", position="upper_edge")
    plotter.screenshot(str(path))
    plotter.close()
    return path
