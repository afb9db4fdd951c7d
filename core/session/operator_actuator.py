"""The ``operator`` actuator kind: a person shown each target cell, whose presses are read from recordings.

``[actuator] kind = "operator"`` takes ``recordings_dir`` (a folder of palpate recordings holding the presses: one
per file, or whole sessions made by ``palpate import session`` / ``palpate record session``, taken in name order;
with several objects one subfolder per object, named as the object) and ``figures`` (also write a PNG of the grid
with the target before each press). A press from a session file is perceived as the session asks (press axis from
the press's motion).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from palpate.core.errors import PalpateError, RecordingError, ValidationError
from palpate.core.names import file_stem, inside
from palpate.core.perception.streams import PressRecording
from palpate.core.session.actuators import ActuatorRequest
from palpate.core.session.operator import ABORT, MAX_PROMPTS, HumanOperator
from palpate.core.session.operator_sessions import SessionFolder
from palpate.core.session.sources import PressTarget
from palpate.core.world.actuator_kinds import ActuatorKind
from palpate.core.world.table_reader import TableReader, resolve_path


@dataclass(frozen=True)
class OperatorOptions:
    """``[actuator]`` options of kind ``operator``.

    Attributes:
        recordings_dir: folder of MCAP recordings, one per press (one subfolder per object with several).
        figures: also write a PNG of the grid with the target before each press.
    """

    recordings_dir: Path | None = None
    figures: bool = True


def parse_options(r: TableReader, base: Path) -> OperatorOptions:
    """Validate the operator's ``[actuator]`` keys; relative paths resolve against ``base``."""
    folder = r.get("recordings_dir", str)
    if not folder:
        raise r.err("recordings_dir", "must name a folder of MCAP recordings, one per press")
    return OperatorOptions(resolve_path(base, folder), r.get("figures", bool, True))


def recordings_folder(folder: Path | None, obj: str, n_objects: int) -> Path:
    """The folder holding one object's press recordings: ``folder`` itself for a one-object scenario, else its
    subfolder named as the object. ValidationError naming ``actuator.recordings_dir`` if it is not there."""
    if folder is None:
        raise ValidationError("actuator.recordings_dir: missing (required for kind 'operator': a folder of MCAP "
                              "recordings, one per press)")
    if not Path(folder).is_dir():
        raise ValidationError(f"actuator.recordings_dir: {folder} is not a folder (expected MCAP recordings, one "
                              "per press, taken in name order)")
    if n_objects == 1:
        return Path(folder)
    sub = Path(folder) / obj
    if not sub.is_dir():
        raise ValidationError(f"actuator.recordings_dir: the scenario explores {n_objects} objects, so each has a "
                              f"subfolder named as the object; {sub} is missing")
    return sub


def folder_streams(folder: Path, input: TextIO, output: TextIO) -> Callable[[PressTarget, int], PressRecording]:
    """Streams for :class:`~palpate.core.session.operator.HumanOperator`: press k is the k-th press held by the
    ``*.mcap`` files of ``folder`` in name order (one press per file, or whole sessions: see
    :mod:`palpate.core.session.operator_sessions`; name per-press files so they sort in press order).

    The folder is listed again at every press, so recordings may arrive while the session runs (the person
    presses, the session is recorded or imported); if press k is not there yet the person is asked to add it and
    confirm again. RecordingError if it never comes.
    """
    presses = SessionFolder(folder)

    def take(target: PressTarget, k: int) -> PressRecording:
        held = 0
        for _ in range(MAX_PROMPTS):
            rec, held = presses.press(k)
            if rec is not None:
                return rec
            output.write(f"   no recording for press {k + 1} in {folder} yet ({held} press(es) in "
                         f"{len(presses.files())} file(s)); record or import it there, then Enter (q to stop): ")
            output.flush()
            line = input.readline()
            if line == "":
                break
            if line.strip().lower() in ABORT:
                raise PalpateError("the operator stopped the exploration")
        raise RecordingError(f"{folder}: press {k + 1} needs its recording, but the folder's "
                             f"{len(presses.files())} file(s) hold {held} press(es)")

    return take


def operator_actuator(request: ActuatorRequest, *, check_only: bool = False):
    """Factory of kind ``operator``: a :class:`~palpate.core.session.operator.HumanOperator` shown each target cell
    (text grid, and a PNG under ``<out>/figures/operator/<object>/`` when ``figures``), whose presses are read from
    ``recordings_dir``. With ``check_only``, only checks the folder."""
    spec: OperatorOptions = request.spec.options
    folder = recordings_folder(spec.recordings_dir, request.obj.name, request.n_objects)
    if check_only:
        return None
    input = request.input if request.input is not None else sys.stdin
    output = request.output if request.output is not None else sys.stderr
    figure_dir = None
    if spec.figures and request.out_dir is not None:
        out = Path(request.out_dir)
        figure_dir = inside(out, out / "figures" / "operator" / file_stem(request.obj.name))
    output.write(f"\nOperator: explore {request.obj.name} ({request.shape[0]} x {request.shape[1]} cells of "
                 f"{request.cell_size * 1e3:.0f} mm, corner at x = {request.origin[0] * 1e3:.1f} mm, "
                 f"y = {request.origin[1] * 1e3:.1f} mm); press recordings from {folder}\n")
    return HumanOperator(request.origin, request.cell_size, request.shape, folder_streams(folder, input, output),
                         input=input, output=output, figure_dir=figure_dir, materials=request.materials)


#: The entry point ``operator`` of ``palpate.actuators``.
OPERATOR = ActuatorKind(keys=("recordings_dir", "figures"), parse=parse_options, make=operator_actuator)
