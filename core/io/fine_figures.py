"""The fine material map's figure: the cell map, the fine map with the walls the presses read and the spots that
read harder or softer than the map says, and the truth, on one 1 mm raster; and a voxel map's lump layer cut at a
few depths above the truth there."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from palpate.core.io.figures import _map_axes, _map_panel, _panel_size, _save, colour_legend, new_figure, rgb_image
from palpate.core.mapping.fine import FineMap
from palpate.core.mapping.lump_layer import LumpLayer

#: Half the length of a read wall's drawn segment, cm.
SEGMENT_CM = 0.4


def plot_fine_map(path: Path, name: str, fine: FineMap, cells: np.ndarray, truth: np.ndarray | None,
                  walls: list[tuple[tuple[float, float], tuple[float, float]]],
                  spots: list[tuple[tuple[float, float], str]] = ()) -> Path:
    """Draw :func:`fine_map_figure` into ``path``."""
    return _save(fine_map_figure(name, fine, cells, truth, walls, spots), path)


def fine_map_figure(name: str, fine: FineMap, cells: np.ndarray, truth: np.ndarray | None,
                    walls: list[tuple[tuple[float, float], tuple[float, float]]],
                    spots: list[tuple[tuple[float, float], str]] = ()):
    """Panels: the cell map's probabilities on the fine raster (``cells``: (ny, nx, M)), the fine map's with each
    read wall (``walls``: its foot (x, y) and normal, m) as a white segment and each stiffness spot (``spots``: its
    centroid (x, y), m, and "harder" or "softer") as a white triangle up or down, and the truth (index per point,
    -1: none) when known."""
    materials = list(fine.materials)
    title = "fine map, read walls in white" + (", spots: harder ^ softer v" if spots else "")
    panels = [(rgb_image(cells), "cell map"), (rgb_image(fine.probabilities), title)]
    if truth is not None and (truth >= 0).any():
        p = np.zeros(truth.shape + (len(materials),))
        p[truth >= 0] = np.eye(len(materials))[truth[truth >= 0]]
        panels.append((rgb_image(p), "ground truth"))
    ny, nx = fine.probabilities.shape[:2]
    panel_w, height = _panel_size(nx / ny, 2.6, 1.3)
    fig = new_figure(panel_w * len(panels) + 0.9, height)
    axes = _map_axes(fig, len(panels), height)
    x0, y0 = fine.origin
    ext = [x0 * 100, (x0 + nx * fine.resolution) * 100, y0 * 100, (y0 + ny * fine.resolution) * 100]
    for ax, (img, title) in zip(axes, panels, strict=True):
        _map_panel(ax, img, ext, title)
    for foot, normal in walls:
        f, t = np.asarray(foot) * 100, np.array([-normal[1], normal[0]]) * SEGMENT_CM
        axes[1].plot([f[0] - t[0], f[0] + t[0]], [f[1] - t[1], f[1] + t[1]], color="white", lw=1.2)
    for (x, y), sign in spots:
        axes[1].plot(x * 100, y * 100, marker="^" if sign == "harder" else "v", ms=7, mfc="white", mec="black",
                     mew=0.8, ls="none")
    axes[1].set_xlim(ext[0], ext[1])
    axes[1].set_ylim(ext[2], ext[3])
    axes[0].set_ylabel("y (cm)")
    fig.suptitle(f"{name}: P(material) as colour ({colour_legend(materials)}) on a {fine.resolution * 1e3:g} mm "
                 "raster", fontsize=10)
    return fig


#: How many depths the lump layer's figure shows.
LAYER_SLICES = 4


def plot_lump_layer(path: Path, name: str, layer: LumpLayer, truth: np.ndarray | None,
                    spots: list[tuple[tuple[float, float], str]] = ()) -> Path:
    """Draw :func:`lump_layer_figure` into ``path``."""
    return _save(lump_layer_figure(name, layer, truth, spots), path)


def lump_layer_figure(name: str, layer: LumpLayer, truth: np.ndarray | None,
                      spots: list[tuple[tuple[float, float], str]] = ()):
    """The lump layer (:mod:`palpate.core.mapping.lump_layer`) cut at :data:`LAYER_SLICES` depths spread over it,
    each stiffness spot (``spots``: centroid (x, y), m, and "harder" or "softer") as a white triangle, above the
    truth at the same depths (``truth``: index per cube (nx, ny, nz), -1 none) when known."""
    materials = list(layer.materials)
    nx, ny, nz = layer.probabilities.shape[:3]
    picks = sorted({min(nz - 1, int((k + 0.5) * nz / LAYER_SLICES)) for k in range(LAYER_SLICES)})
    rows = [("lump layer", [np.transpose(layer.probabilities[:, :, i], (1, 0, 2)) for i in picks])]
    if truth is not None and (truth >= 0).any():
        eye = np.vstack([np.eye(len(materials)), np.zeros(len(materials))])  # -1 (none) shows black
        rows.append(("truth", [np.transpose(eye[truth[:, :, i]], (1, 0, 2)) for i in picks]))
    panel_w, height = _panel_size(nx / ny, 2.2, 0.9)
    fig = new_figure(panel_w * len(picks) + 0.9, (height - 0.9) * len(rows) + 1.4)
    axes = fig.subplots(len(rows), len(picks), squeeze=False, sharex=True, sharey=True)
    fig.subplots_adjust(left=0.7 / fig.get_figwidth(), right=1 - 0.2 / fig.get_figwidth(),
                        bottom=0.55 / fig.get_figheight(), top=1 - 0.75 / fig.get_figheight(), wspace=0.12,
                        hspace=0.35)
    x0, y0 = layer.origin
    ext = [x0 * 100, (x0 + nx * layer.resolution) * 100, y0 * 100, (y0 + ny * layer.resolution) * 100]
    for r, (what, images) in enumerate(rows):
        for c, (i, p) in enumerate(zip(picks, images, strict=True)):
            ax = axes[r, c]
            _map_panel(ax, rgb_image(p), ext, f"{what}, {(i + 0.5) * layer.resolution * 1e3:.1f} mm down")
            if r == 0:
                for (x, y), sign in spots:
                    ax.plot(x * 100, y * 100, marker="^" if sign == "harder" else "v", ms=6, mfc="white",
                            mec="black", mew=0.8, ls="none")
                ax.set_xlim(ext[0], ext[1])
                ax.set_ylim(ext[2], ext[3])
            if c == 0:
                ax.set_ylabel("y (cm)")
            else:
                ax.tick_params(labelleft=False)
    fig.suptitle(f"{name}: read lumps below the surface, P(material) as colour ({colour_legend(materials)})",
                 fontsize=10)
    return fig
