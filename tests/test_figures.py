"""Figures: drawn in the background they are the same files as drawn inline; coinciding progress lines stay
visible; the entropy scale says it is linear; the 3-D render is labelled and quiet when headless."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

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
    assert fig.entropy_label(10.0) == "entropy H, base-10 logarithm (linear colour scale)"


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
