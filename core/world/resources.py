"""Data shipped inside the package: scenario files (``palpate.scenarios``, the repository's ``scenarios/``) and
models (``palpate.models``: finger descriptions, calibration tables, haptic-material maps), found with
:mod:`importlib.resources` so they work from a wheel as from a checkout."""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path

from palpate.core.errors import ValidationError

SCENARIOS_PACKAGE = "palpate.scenarios"
MODELS_PACKAGE = "palpate.models"


def _package_dir(package: str) -> Path:
    try:
        root = Path(str(files(package)))
    except ModuleNotFoundError:
        raise ValidationError(f"the package data {package!r} is not installed (reinstall palpate)") from None
    if not root.is_dir():
        raise ValidationError(f"the package data {package!r} is not a folder on disk ({root}); install palpate "
                              "from a wheel or a checkout, not a zip")
    return root


def models_dir() -> Path:
    """The shipped models folder (``models/`` of a checkout)."""
    return _package_dir(MODELS_PACKAGE)


def scenarios_dir() -> Path:
    """The shipped scenarios folder (``scenarios/`` of a checkout)."""
    return _package_dir(SCENARIOS_PACKAGE)


@dataclass(frozen=True)
class ScenarioInfo:
    """A shipped scenario: its name for ``palpate run NAME``, its file, its one-line description and its kind
    ("scenario", or "sweep" for a sweep file, which ``palpate sweep`` runs and ``palpate run`` does not)."""

    name: str
    path: Path
    description: str
    kind: str = "scenario"


def shipped_scenarios() -> list[ScenarioInfo]:
    """Every scenario file shipped with palpate, by name (sweeps as ``sweeps/NAME``)."""
    root = scenarios_dir()
    out = []
    for path in sorted(root.rglob("*.toml")):
        try:
            doc = tomllib.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
            doc = {}
        head = doc.get("scenario") or doc.get("sweep") or {}
        description = head.get("description", "") if isinstance(head, dict) else ""
        kind = "sweep" if "sweep" in doc and "scenario" not in doc else "scenario"
        out.append(ScenarioInfo(path.relative_to(root).with_suffix("").as_posix(), path, str(description), kind))
    return out


def find_scenario(arg: str | Path) -> Path:
    """A scenario file from the command line: an existing path as given, else the name of a shipped scenario
    (``thesis_ch6``, ``thesis_ch6.toml`` or ``sweeps/tiny``). ValidationError listing the shipped names if neither."""
    path = Path(arg)
    if path.exists():
        return path
    name = path.as_posix().removesuffix(".toml")
    for info in shipped_scenarios():
        if info.name == name:
            return info.path
    names = ", ".join(i.name for i in shipped_scenarios())
    raise ValidationError(f"{arg}: no such file, and not the name of a shipped scenario ({names}); "
                          "see palpate scenarios list")
