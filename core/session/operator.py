"""A human operator as the actuator: show the next cell to press, wait for the press, take its streams.

:class:`HumanOperator` has the same ``press(PressTarget) -> PressRecording`` as the simulated or the Dynamixel
finger, so the run loop drives a person exactly as it drives a robot. For each press it prints a text grid with
the target marked (and the map's current estimate when the loop shows it one), writes the same as a PNG figure
when given a folder, waits for the operator to confirm, then takes the press's raw streams from ``streams``: a
callable (e.g. reading the Tekscan and Liberty devices for the time of the press) or a list of recording files,
one per press. Input and output streams are injectable, so a script (or a test) can play the operator.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TextIO

import numpy as np

from palpate.core import files
from palpate.core.errors import PalpateError, RecordingError, ValidationError
from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.recording import recording_to_press_recording
from palpate.core.mapping.geometry import plane_probabilities
from palpate.core.perception.streams import PressRecording
from palpate.core.session.sources import PressTarget

CONFIRM = ("", "y", "yes", "done", "ok")
ABORT = ("q", "quit", "abort")
MAX_PROMPTS = 5


def recordings_from_files(paths: Sequence[str | Path]) -> Callable[[PressTarget, int], PressRecording]:
    """A stream source that returns the k-th press from the k-th MCAP recording (palpate format).

    Raises RecordingError when asked for more presses than there are files, naming how many there are.
    """
    files = [Path(p) for p in paths]

    def take(target: PressTarget, k: int) -> PressRecording:
        if k >= len(files):
            raise RecordingError(f"press {k + 1} asked for, but only {len(files)} recording file(s) were given")
        rec = recording_to_press_recording(read_recording(files[k]))
        rec.meta = {**rec.meta, "file": str(files[k])}
        return rec

    return take


def text_grid(shape: tuple[int, int], target: tuple[int, int], pressed: set[tuple[int, int]] | None = None,
              estimate: np.ndarray | None = None, symbols: str = "") -> str:
    """The grid as text, row 1 at the top as on a sheet laid over the object, with the target as ``X``.

    Args:
        shape: (nx, ny) cells.
        target: (ix, iy), 0-based.
        pressed: cells pressed before, drawn as ``o`` (when no estimate is given).
        estimate: optional (ny, nx) index of the most probable material, -1 for undecided; drawn with
            ``symbols[m]`` (default: the first letters of the alphabet), lower case where not yet pressed.
        symbols: one character per material.
    """
    nx, ny = shape
    pressed = pressed or set()
    letters = symbols or "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
    width = len(str(nx))
    lines = ["    " + " ".join(f"{c + 1:>{width}}" for c in range(nx))]
    for iy in range(ny - 1, -1, -1):
        cells = []
        for ix in range(nx):
            if (ix, iy) == target:
                ch = "X"
            elif estimate is not None and estimate[iy, ix] >= 0:
                ch = letters[int(estimate[iy, ix])]
                ch = ch if (ix, iy) in pressed else ch.lower()
            else:
                ch = "o" if (ix, iy) in pressed else "."
            cells.append(f"{ch:>{width}}")
        lines.append(f"{iy + 1:>3} " + " ".join(cells))
    return "\n".join(lines)


class HumanOperator:
    """Prompts a person to press each target and returns that press's streams.

    Args:
        origin: (x0, y0) of the map grid's corner, m.
        cell_size: grid cell side, m.
        shape: (nx, ny) cells.
        streams: where a confirmed press's streams come from: a callable ``(target, k) -> PressRecording``
            (k counts presses from 0), or a sequence of MCAP recording paths, one per press.
        input: text stream the confirmation is read from (default: stdin).
        output: text stream the prompt is written to (default: stdout).
        figure_dir: if given, a PNG of the grid with the target is written there before each press
            (``operator_press_001.png``, ...).
        materials: names of the map's materials, for the legend of the text grid.
    """

    def __init__(self, origin: tuple[float, float], cell_size: float, shape: tuple[int, int],
                 streams: Callable[[PressTarget, int], PressRecording] | Sequence[str | Path], *,
                 input: TextIO | None = None, output: TextIO | None = None, figure_dir: str | Path | None = None,
                 materials: Sequence[str] = ()):
        if not (np.isfinite(cell_size) and cell_size > 0):
            raise ValidationError(f"cell_size must be a finite number > 0 m, got {cell_size!r}")
        if len(shape) != 2 or not all(isinstance(v, (int, np.integer)) and v > 0 for v in shape):
            raise ValidationError(f"shape must be (nx, ny) positive integers, got {shape!r}")
        self.origin = (float(origin[0]), float(origin[1]))
        self.cell_size = float(cell_size)
        self.shape = (int(shape[0]), int(shape[1]))
        self.streams = streams if callable(streams) else recordings_from_files(list(streams))
        self.input = input if input is not None else sys.stdin
        self.output = output if output is not None else sys.stdout
        self.figure_dir = Path(figure_dir) if figure_dir is not None else None
        self.materials = list(materials)
        self.pressed: set[tuple[int, int]] = set()
        self.figures: list[Path] = []
        self._estimate: np.ndarray | None = None
        self._k = 0

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(ix, iy) of the cell holding (x, y), m; ValidationError outside the grid."""
        ix = int(np.floor((x - self.origin[0]) / self.cell_size))
        iy = int(np.floor((y - self.origin[1]) / self.cell_size))
        nx, ny = self.shape
        if not (0 <= ix < nx and 0 <= iy < ny):
            raise ValidationError(f"target ({x:.4f}, {y:.4f}) m is outside the operator's {nx}x{ny} grid")
        return ix, iy

    def show_map(self, grid, post=None) -> None:
        """Remember the map's current estimate (most probable material, -1 where undecided) for the next prompt."""
        m = post if post is not None else grid
        p = plane_probabilities(m.probabilities)  # a voxel map's surface layer
        top2 = np.sort(p, axis=-1)[..., -2:]
        est = p.argmax(axis=-1)
        est[(top2[..., 1] - top2[..., 0]) <= 1e-9] = -1
        self._estimate = est
        if not self.materials:
            self.materials = list(getattr(grid, "materials", []))

    def press(self, target: PressTarget) -> PressRecording:
        """Prompt for a press at ``target``, wait for confirmation, and return the press's raw streams.

        Raises:
            PalpateError: the operator aborted ("q") or the input ended before a confirmation.
            ValidationError: the target is outside the grid, or the stream source returned no PressRecording.
        """
        cell = self.cell_of(target.x, target.y)
        k = self._k
        out = self.output
        symbols = "".join(n[:1].upper() for n in self.materials)
        if len(set(symbols)) != len(symbols):
            symbols = ""
        out.write(f"\nPress {k + 1}: cell column {cell[0] + 1}, row {cell[1] + 1} "
                  f"(x = {target.x * 1e3:.1f} mm, y = {target.y * 1e3:.1f} mm)")
        if target.depth is not None:
            out.write(f", about {target.depth * 1e3:.1f} mm deep")
        if target.force is not None:
            out.write(f", at most {target.force:.1f} N")
        out.write("\n" + text_grid(self.shape, cell, self.pressed, self._estimate, symbols) + "\n")
        if self._estimate is not None and self.materials:
            legend = symbols or "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
            out.write("   " + ", ".join(f"{legend[i]} = {n}" for i, n in enumerate(self.materials))
                      + " (lower case: estimated, not pressed yet)\n")
        if self.figure_dir is not None:
            self.figures.append(self._figure(cell, k))
            out.write(f"   figure: {self.figures[-1]}\n")
        self._wait_for_confirmation()
        rec = self.streams(target, k)
        if not isinstance(rec, PressRecording):
            raise ValidationError(f"the operator's stream source returned {type(rec).__name__} for press {k + 1}; "
                                  "expected a PressRecording")
        rec.meta = {**rec.meta, "source": "operator", "target_xy": [target.x, target.y],
                    "cell": [cell[0] + 1, cell[1] + 1]}
        self.pressed.add(cell)
        self._k += 1
        return rec

    def _wait_for_confirmation(self) -> None:
        for _ in range(MAX_PROMPTS):
            self.output.write("   press the cell, then Enter (q to stop): ")
            self.output.flush()
            line = self.input.readline()
            if line == "":
                raise PalpateError("operator input ended before the press was confirmed")
            answer = line.strip().lower()
            if answer in CONFIRM:
                return
            if answer in ABORT:
                raise PalpateError("the operator stopped the exploration")
            self.output.write(f"   did not understand {line.strip()!r}; Enter confirms the press, q stops\n")
        raise PalpateError(f"no confirmation after {MAX_PROMPTS} prompts")

    def _figure(self, cell: tuple[int, int], k: int) -> Path:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        nx, ny = self.shape
        c = self.cell_size * 1e3
        x0, y0 = self.origin[0] * 1e3, self.origin[1] * 1e3
        fig, ax = plt.subplots(figsize=(max(4.0, nx * 0.4), max(3.0, ny * 0.4)))
        if self._estimate is not None:
            est = np.ma.masked_less(self._estimate, 0)
            ax.imshow(est, origin="lower", extent=(x0, x0 + nx * c, y0, y0 + ny * c), cmap="Pastel1",
                      vmin=0, vmax=max(8, len(self.materials)))
        for ix, iy in self.pressed:
            ax.plot(x0 + (ix + 0.5) * c, y0 + (iy + 0.5) * c, "o", color="0.4", ms=4)
        ax.add_patch(plt.Rectangle((x0 + cell[0] * c, y0 + cell[1] * c), c, c, fill=False, ec="red", lw=2.5))
        ax.plot(x0 + (cell[0] + 0.5) * c, y0 + (cell[1] + 0.5) * c, "x", color="red", ms=12, mew=2.5)
        ax.set_xticks(x0 + np.arange(nx + 1) * c, minor=True)
        ax.set_yticks(y0 + np.arange(ny + 1) * c, minor=True)
        ax.grid(which="minor", color="0.8", lw=0.5)
        ax.set_xlim(x0, x0 + nx * c)
        ax.set_ylim(y0, y0 + ny * c)
        ax.set_aspect("equal")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        ax.set_title(f"press {k + 1}: column {cell[0] + 1}, row {cell[1] + 1}")
        self.figure_dir.mkdir(parents=True, exist_ok=True)
        path = self.figure_dir / f"operator_press_{k + 1:03d}.png"
        fig.tight_layout()
        with files.writing(path):
            fig.savefig(path, dpi=90)
        plt.close(fig)
        return path
