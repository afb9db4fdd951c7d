"""Figures of a run (PNG), drawn headless with matplotlib's Agg backend (and pyvista off-screen for 3-D).

- ``training_series.png``: c_P, c_A, c_D over time for the training presses, one column per material (seed 000
  Fig. 6.8-6.10);
- ``interaction_profiles.png``: (c_A, c_D, c_P) of every training press per material (Fig. 6.11);
- ``<object>_map.png``: the map as an RGB probability image (red, green, blue = P(material 1, 2, 3), Fig. 6.22-6.26)
  at k = 0, mid-way, final, and after post-processing, with the pressed cells outlined;
- ``<object>_entropy.png``: the entropy map before and after post-processing;
- ``<object>_progress.png``: mean entropy and accuracy of explored cells against presses;
- voxel maps: ``<object>_columns.png`` (seed 001 Fig. 4 column view) and ``<object>_voxels_3d.png`` (pyvista).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.mapping.geometry import MapGeometry
from palpate.core.mapping.probability import entropy
from palpate.core.mapping.snapshot import MapSnapshot
from palpate.core.perception.press import PressResult


@dataclass(frozen=True)
class ProgressSeries:
    """One object's exploration progress: press numbers, mean map entropy and explored-cell accuracy after each
    press (NaN where there is no truth)."""

    name: str
    k: np.ndarray
    mean_entropy: np.ndarray
    accuracy_explored: np.ndarray


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def rgb_image(probabilities: np.ndarray) -> np.ndarray:
    """(…, M) probabilities -> (…, 3) RGB in [0, 1]: red, green, blue = P(material 1, 2, 3).

    With more than three materials the rest mix in through a fixed palette; with two, blue stays 0.
    """
    p = np.asarray(probabilities, dtype=float)
    m = p.shape[-1]
    palette = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, 0, 1], [0, 1, 1], [0.5, 0.5, 0.5]], float)
    if m > len(palette):
        palette = np.vstack([palette, np.full((m - len(palette), 3), 0.5)])
    return np.clip(p @ palette[:m], 0.0, 1.0)


def plot_training_series(path: Path, training: Mapping[str, Sequence[PressResult]]) -> Path:
    """c_P, c_A (mm^2), c_D (mm) against time for every training press, presses laid end to end."""
    plt = _plt()
    names = list(training)
    fig, axes = plt.subplots(3, len(names), figsize=(4.2 * len(names), 7), sharex="col", squeeze=False)
    for j, name in enumerate(names):
        t_off = 0.0
        for res in training[name]:
            pr = res.press
            if pr is None:
                continue
            t = pr.t - pr.t[0] + t_off
            axes[0, j].plot(t, pr.c_P, color="C3", lw=1)
            axes[1, j].plot(t, pr.c_A * 1e6, color="C2", lw=1)
            axes[2, j].plot(t, pr.c_D * 1e3, color="C0", lw=1)
            t_off = t[-1] + 0.2
        axes[0, j].set_title(name)
        axes[2, j].set_xlabel("press phases, laid end to end (s)")
    for i, label in enumerate(["c_P (counts)", "c_A (mm²)", "c_D (mm)"]):
        axes[i, 0].set_ylabel(label)
    fig.suptitle("Contact features during the training presses (press phase of each press)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_interaction_profiles(path: Path, training: Mapping[str, Sequence[PressResult]]) -> Path:
    """3-D scatter of (c_A, c_D, c_P) per material: the contact-interaction signature."""
    plt = _plt()
    fig = plt.figure(figsize=(7, 5.5))
    ax = fig.add_subplot(projection="3d")
    for j, (name, results) in enumerate(training.items()):
        presses = [r.press for r in results if r.press is not None]
        xs = np.concatenate([p.c_A * 1e6 for p in presses] or [np.zeros(0)])
        ys = np.concatenate([p.c_D * 1e3 for p in presses] or [np.zeros(0)])
        zs = np.concatenate([p.c_P for p in presses] or [np.zeros(0)])
        ax.scatter(xs, ys, zs, s=6, color=rgb_image(np.eye(len(training))[j]), label=name, depthshade=False)
    ax.set_xlabel("c_A (mm²)")
    ax.set_ylabel("c_D (mm)")
    ax.set_zlabel("c_P (counts)")
    ax.legend(loc="upper left")
    ax.set_title("Contact-interaction profile per reference material")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _extent(geometry: MapGeometry, shape: tuple[int, int]) -> list[float]:
    """imshow extent in cm of a (ny, nx) image of the map."""
    (x0, y0), c = geometry.origin, geometry.cell_size
    ny, nx = shape
    return [x0 * 100, (x0 + nx * c) * 100, y0 * 100, (y0 + ny * c) * 100]


def plot_map_snapshots(path: Path, name: str, snapshots: Sequence[MapSnapshot], geometry: MapGeometry,
                       truth: np.ndarray | None = None) -> Path:
    """RGB probability maps at k = 0, mid-way, final and post-processed (2-D grid), plus the ground truth."""
    plt = _plt()
    materials = list(geometry.materials)
    panels: list[MapSnapshot | None] = list(snapshots) + ([None] if truth is not None else [])
    ny, nx = (truth.shape if not snapshots else snapshots[0].probabilities.shape)[:2]
    aspect = max(1.0, nx / ny)
    fig, axes = plt.subplots(1, len(panels), figsize=(min(20.0, 3.0 * aspect * len(panels)), 3.6), squeeze=False,
                             layout="constrained")
    for ax, snap in zip(axes[0], panels, strict=True):
        if snap is None:  # the ground-truth panel
            p = np.zeros(truth.shape + (len(materials),))
            valid = truth >= 0
            p[valid] = np.eye(len(materials))[truth[valid]]
            img, explored, label = rgb_image(p), None, "ground truth"
        else:
            img, explored, label = rgb_image(snap.probabilities), snap.explored, snap.label
        ext = _extent(geometry, img.shape[:2])
        ax.imshow(img, origin="lower", extent=ext, interpolation="nearest")
        if explored is not None and label != "post-processed":
            c = geometry.cell_size * 100
            for iy, ix in np.argwhere(explored):
                ax.add_patch(plt.Rectangle((ext[0] + ix * c, ext[2] + iy * c), c, c, fill=False, ec="white", lw=1.2))
        ax.set_title(label)
        ax.set_xlabel("x (cm)")
    axes[0, 0].set_ylabel("y (cm)")
    legend = " · ".join(f"{c}={m}" for c, m in zip(("red", "green", "blue"), materials, strict=False))
    fig.suptitle(f"{name}: P(material) as RGB ({legend}); pressed cells outlined")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_entropy(path: Path, name: str, before: np.ndarray, after: np.ndarray, geometry: MapGeometry) -> Path:
    """Entropy per cell (in the map's entropy base) before and after post-processing, on one colour scale."""
    plt = _plt()
    base = geometry.entropy_base
    hb, ha = entropy(before, base=base), entropy(after, base=base)
    vmax = float(np.log(before.shape[-1]) / np.log(base))
    ny, nx = hb.shape
    width = min(14.0, 2 * 3.2 * max(1.0, nx / ny) + 1.5)
    fig, axes = plt.subplots(1, 2, figsize=(width, 3.6), squeeze=False, layout="constrained")
    for ax, h, title in zip(axes[0], (hb, ha), ("final map", "after post-processing"), strict=True):
        im = ax.imshow(h, origin="lower", extent=_extent(geometry, h.shape), vmin=0, vmax=vmax, cmap="magma")
        ax.set_title(f"{title}\nmean H = {h.mean():.3f}")
        ax.set_xlabel("x (cm)")
    axes[0, 0].set_ylabel("y (cm)")
    fig.colorbar(im, ax=axes[0].tolist(), label=f"entropy (log{base:g})")
    fig.suptitle(f"{name}: map entropy")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_progress(path: Path, series: Sequence[ProgressSeries]) -> Path:
    """Mean entropy and accuracy of the explored cells after each press, one line per object."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.4))
    for s in series:
        a1.plot(s.k, s.mean_entropy, marker="o", ms=3, label=s.name)
        a2.plot(s.k, s.accuracy_explored, marker="o", ms=3, label=s.name)
    a1.set_xlabel("press k")
    a1.set_ylabel("mean entropy of the map")
    a2.set_xlabel("press k")
    a2.set_ylabel("accuracy of explored cells")
    a2.set_ylim(-0.05, 1.05)
    a1.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_voxel_columns(path: Path, name: str, grid, post, materials: list[str]) -> Path:
    """Seed 001 Fig. 4: explored columns as stacks of RGB voxels, before and after post-processing."""
    plt = _plt()
    explored_cols = np.argwhere(np.asarray(grid.explored).any(axis=2))
    cols = explored_cols[: min(len(explored_cols), 24)]
    fig, axes = plt.subplots(2, 1, figsize=(max(6, 0.45 * len(cols) + 2), 5), squeeze=False)
    for ax, g, title in ((axes[0, 0], grid, "explored"), (axes[1, 0], post, "after post-processing")):
        if len(cols):
            strip = np.stack([rgb_image(g.probabilities[ix, iy]) for ix, iy in cols], axis=1)  # (nz, ncols, 3)
            ax.imshow(strip, aspect="auto", interpolation="nearest")
            ax.set_xticks(range(len(cols)), [f"{ix},{iy}" for ix, iy in cols], rotation=90, fontsize=7)
        ax.set_ylabel("voxel layer (0 = surface)")
        ax.set_title(f"{name}: voxel columns, {title}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def render_voxels_3d(path: Path, grid, cell_size: float) -> Path | None:
    """Off-screen pyvista render of the explored voxels coloured by P(material) (None if pyvista is missing)."""
    try:
        import pyvista as pv
    except ImportError:
        return None
    pv.OFF_SCREEN = True
    probs = np.asarray(grid.probabilities)
    explored = np.asarray(grid.explored)
    nx, ny, nz = explored.shape
    img = pv.ImageData(dimensions=(nx + 1, ny + 1, nz + 1), spacing=(cell_size * 100,) * 3)
    # voxel layer 0 is the surface; flip z so the picture is upright.
    colors = (rgb_image(probs[:, :, ::-1]) * 255).astype(np.uint8)
    img.cell_data["rgb"] = colors.reshape(-1, 3, order="F")
    img.cell_data["explored"] = explored[:, :, ::-1].reshape(-1, order="F").astype(np.uint8)
    shown = img.threshold(0.5, scalars="explored")
    plotter = pv.Plotter(off_screen=True, window_size=(800, 600))
    if shown.n_cells:
        plotter.add_mesh(shown, scalars="rgb", rgb=True, show_edges=True)
    plotter.add_mesh(img.outline(), color="black")
    plotter.add_axes()
    plotter.screenshot(str(path))
    plotter.close()
    return path
