"""Figures: drawn in the background they are the same files as drawn inline; coinciding progress lines stay
visible; the entropy scale says it is linear; the 3-D render is labelled and quiet when headless."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

from palpate.core.errors import ValidationError
from palpate.core.io import figures as fig
from palpate.core.mapping.geometry import MapGeometry
from palpate.core.mapping.snapshot import MapSnapshot
from palpate.core.session.figure_jobs import FigureDrawer, FigureJob

GEOMETRY = MapGeometry("grid2d", ("soft", "medium", "hard"), (0.0, 0.0), 0.01, (8, 5))


def _jobs(rng) -> list[FigureJob]:
    p = rng.dirichlet([1, 1, 1], size=(5, 8))
    explored = rng.random((5, 8)) < 0.3
    snaps = (MapSnapshot("k = 0", np.full((5, 8, 3), 1 / 3), np.zeros((5, 8), bool)),
             MapSnapshot("k = 4", p, explored), MapSnapshot("post-processed", p, explored))
    series = [fig.ProgressSeries("A", np.arange(1, 6), np.linspace(0.4, 0.2, 5), np.ones(5))]
    return [FigureJob("m_map.png", fig.plot_map_snapshots, ("m", snaps, GEOMETRY, rng.integers(0, 3, (5, 8)))),
            FigureJob("m_entropy.png", fig.plot_entropy, ("m", p, p, GEOMETRY)),
            FigureJob("progress.png", fig.plot_progress, (series,))]


def test_background_and_inline_drawing_write_the_same_files(tmp_path, rng):
    jobs = _jobs(rng)
    with FigureDrawer(tmp_path / "bg", background=True) as drawer:
        drawer.submit(jobs)
        bg = drawer.finish()
    with FigureDrawer(tmp_path / "inline", background=False) as drawer:
        drawer.submit(jobs)
        inline = drawer.finish()
    assert [p.name for p in bg] == [p.name for p in inline] == [j.file for j in jobs]
    for a, b in zip(bg, inline, strict=True):
        assert a.read_bytes() == b.read_bytes(), a.name


def test_a_failing_figure_is_reported(tmp_path):
    with FigureDrawer(tmp_path, background=True) as drawer:
        drawer.submit([FigureJob("bad.png", fig.plot_progress, ("not a list of series",))])
        with pytest.raises(AttributeError):
            drawer.finish()


def _pixels_near(img: np.ndarray, hex_colour: str, tol: int = 40) -> int:
    rgb = np.array([int(hex_colour[i:i + 2], 16) for i in (1, 3, 5)])
    return int(np.sum(np.all(np.abs(img[..., :3].astype(int) - rgb) < tol, axis=-1)))


def test_coinciding_progress_lines_both_stay_visible(tmp_path):
    k = np.arange(1, 11)
    same = (np.linspace(0.47, 0.44, 10), np.ones(10))
    series = [fig.ProgressSeries("Object_1", k, *same), fig.ProgressSeries("Object_3", k, *same)]
    img = np.asarray(Image.open(fig.plot_progress(tmp_path / "p.png", series)).convert("RGB"))
    # matplotlib's first two cycle colours: the line drawn underneath must still show around the top one
    assert _pixels_near(img, "#1f77b4") > 500 and _pixels_near(img, "#ff7f0e") > 100


def test_entropy_colour_bar_says_its_scale_is_linear():
    assert fig.entropy_label(10.0) == "entropy H (hartley: base-10 logarithm; linear colour scale)"
    assert fig.entropy_label(2.0).startswith("entropy H (bit:")


RENDER = """
import numpy as np
from types import SimpleNamespace
from palpate.core.io.figures import render_voxels_3d
rng = np.random.default_rng(0)
grid = SimpleNamespace(probabilities=rng.dirichlet([1, 1, 1], size=(4, 3, 3)), explored=rng.random((4, 3, 3)) < 0.6)
print(render_voxels_3d(__import__("sys").argv[1], grid, 0.01, "Lump", ["soft", "medium", "hard"]))
"""


def test_voxel_render_is_headless_and_quiet(tmp_path):
    pytest.importorskip("pyvista", reason="the 3-D render needs the 'viz' extra (pip install 'palpate[viz]')")
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "PYVISTA_OFF_SCREEN")}
    out = tmp_path / "v.png"
    done = subprocess.run([sys.executable, "-c", RENDER, str(out)], capture_output=True, text=True, env=env,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stderr == "" and Path(done.stdout.strip()) == out
    img = np.asarray(Image.open(out).convert("RGB"))
    assert img.shape[0] > 500 and _pixels_near(img, "#ffffff", 5) > 0.3 * img.shape[0] * img.shape[1]


# Machado, Oliveira & Fernandes (2009) simulation matrices, severity 1, on linear RGB
_CVD = {
    "protanopia": [[0.152286, 1.052583, -0.204868], [0.114503, 0.786281, 0.099216], [-0.003882, -0.048116, 1.051998]],
    "deuteranopia": [[0.367322, 0.860646, -0.227968], [0.280085, 0.672501, 0.047413],
                     [-0.011820, 0.042940, 0.968881]],
    "tritanopia": [[1.255528, -0.076749, -0.178779], [-0.078411, 0.930809, 0.147602], [0.004733, 0.691367, 0.303900]],
}


def _chromaticity(srgb: np.ndarray, matrix) -> np.ndarray:
    lin = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    seen = np.clip(lin @ np.asarray(matrix).T, 0, None)
    return seen / seen.sum(axis=-1, keepdims=True)


@pytest.mark.parametrize("deficiency", sorted(_CVD))
def test_the_material_colours_stay_apart_under_colour_blindness(deficiency):
    # the three colours of a three-material map differ in hue (not only in lightness) as a colour-blind reader
    # sees them (L1 distance of the chromaticities); red and green, (1, 0, 0) and (0, 1, 0), differ by under 0.03
    # under protanopia and deuteranopia, the closest pair here (blue, bluish green under tritanopia) by 0.15
    c = _chromaticity(fig.palette(3), _CVD[deficiency])
    for i in range(3):
        for j in range(i + 1, 3):
            assert np.abs(c[i] - c[j]).sum() > 0.1, (deficiency, fig.COLOUR_NAMES[i], fig.COLOUR_NAMES[j])
    assert len(set(fig.COLOUR_NAMES)) == len(fig.COLOUR_NAMES) and "red" not in fig.COLOUR_NAMES[:3]


_UNIT = re.compile(r"\([^()]*\w[^()]*\)")


def _axes_labels_have_units(figure) -> int:
    """Every axis of ``figure`` has a label with a unit in parentheses (a panel sharing an axis with a labelled one
    counts as labelled); every panel that is not a colour bar draws something. Returns the number of panels."""
    panels = [ax for ax in figure.axes if ax.get_label() != "<colorbar>"]
    for ax in figure.axes:
        if ax.get_label() == "<colorbar>":
            assert _UNIT.search(ax.get_ylabel()), ax.get_ylabel()
            continue
        assert ax.has_data(), f"empty panel {ax.get_title()!r}"
        xlabels = [ax.get_xlabel()] + [o.get_xlabel() for o in panels if ax.get_shared_x_axes().joined(ax, o)]
        assert any(_UNIT.search(x) for x in xlabels), (ax.get_title(), xlabels)
        ylabels = [ax.get_ylabel()] + [o.get_ylabel() for o in panels if ax.get_shared_y_axes().joined(ax, o)]
        assert any(_UNIT.search(y) for y in ylabels), (ax.get_title(), ylabels)
        if hasattr(ax, "get_zlabel"):
            assert _UNIT.search(ax.get_zlabel()), ax.get_zlabel()
    return len(panels)


def _press(rng, scale):
    t = np.linspace(0, 1, 20)
    return SimpleNamespace(press=SimpleNamespace(t=t, c_P=scale * t ** 1.5, c_A=1e-5 * t, c_D=2e-3 * t))


def test_every_figure_labels_every_axis_with_its_unit_and_has_no_empty_panel(rng):
    training = {"soft": [_press(rng, 1.0) for _ in range(3)], "hard": [_press(rng, 4.0) for _ in range(3)]}
    assert _axes_labels_have_units(fig.training_series_figure(training)) == 3
    assert _axes_labels_have_units(fig.interaction_profiles_figure(training)) == 1
    jobs = _jobs(rng)
    name, snaps, geometry, truth = jobs[0].args
    # the k = 0 snapshot (nothing pressed, one flat colour) is left out: k = 4, post-processed, ground truth
    assert _axes_labels_have_units(fig.map_snapshots_figure(name, snaps, geometry, truth)) == 3
    assert _axes_labels_have_units(fig.entropy_figure(*jobs[1].args)) == 2
    assert _axes_labels_have_units(fig.progress_figure(*jobs[2].args)) == 2
    explored = rng.random((4, 3, 3)) < 0.5
    grid = SimpleNamespace(probabilities=rng.dirichlet([1, 1, 1], size=(4, 3, 3)), explored=explored)
    assert _axes_labels_have_units(fig.voxel_columns_figure("v", grid, grid, ["a", "b", "c"])) == 2
    with pytest.raises(ValidationError, match="no explored voxel column"):
        fig.voxel_columns_figure("v", SimpleNamespace(probabilities=grid.probabilities, explored=explored & False),
                                 grid, ["a", "b", "c"])


def test_a_map_is_drawn_in_the_material_colours():
    p = np.zeros((1, 3, 3))
    p[0, [0, 1, 2], [0, 1, 2]] = 1.0
    assert np.allclose(fig.rgb_image(p)[0], fig.palette(3))
    assert fig.colour_legend(["a", "b"]) == f"{fig.COLOUR_NAMES[0]} = a · {fig.COLOUR_NAMES[1]} = b"


def test_the_sim_vs_real_figure_labels_its_axes_with_units_and_refuses_to_be_empty(rng):
    from palpate.core.io.realism_figures import sim_vs_real_figure
    from palpate.core.perception.param_stats import PressTable

    rows = tuple(rng.normal(1.0 + i, 0.1, (6, 6)) for i in range(2))
    real = PressTable(("soft", "hard"), rows)
    sim = PressTable(("soft", "hard"), tuple(r * 1.1 for r in rows))
    assert _axes_labels_have_units(sim_vs_real_figure(sim, real)) == 4
    with pytest.raises(ValidationError, match="no material has more than two"):
        sim_vs_real_figure(sim, PressTable(("other",), rows[:1]))
