"""Limits on everything palpate reads, checked before anything is allocated (docs/limits.md lists them).

A hostile or broken file must not take gigabytes: a size declared in a file (a PNG's pixels, an NPZ array's
shape, a scenario's grid or taxel pad) or the size of the file itself is compared with a limit first. Each limit
has a name; a user who really needs more raises it for one command with ``palpate --limit NAME=VALUE ...`` or for
a shell with ``PALPATE_LIMITS="NAME=VALUE,NAME=VALUE"`` (read when a limit is checked, so sweep workers and Ray
tasks started from that environment see it too).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

from palpate.core.errors import ValidationError

ENV = "PALPATE_LIMITS"


@dataclass(frozen=True)
class Limit:
    """One limit: its name, default value, unit and what it bounds."""

    name: str
    default: float
    unit: str
    what: str


LIMITS = {lim.name: lim for lim in (
    Limit("text_mb", 16, "MB", "size of a text file read whole: JSON, TOML, CSV (memories, scenarios, sweeps, "
          "map sidecars, manifests, params tables, finger descriptions)"),
    Limit("json_depth", 64, "levels", "nesting depth of a JSON document"),
    Limit("npz_mb", 512, "MB", "size of a map NPZ file, and the decoded size of each array in it"),
    Limit("mesh_mb", 256, "MB", "size of a mesh file an object of a scenario names"),
    Limit("png_pixels", 16e6, "pixels", "pixels of one haptic-material PNG, checked before it is decoded"),
    Limit("map_cells", 4e6, "cells", "cells of one map (columns x rows x layers)"),
    Limit("taxels", 4096, "taxels", "taxels of a scenario's fingertip pad (rows x cols)"),
    Limit("materials", 1000, "materials", "materials in a memory, a map or a haptic-material folder"),
    Limit("sweep_variants", 10000, "variants", "variants of one sweep (the product of its axes)"),
    Limit("mcap_mb", 64, "MB", "an MCAP record read into memory, and an MCAP chunk once decompressed"),
    Limit("mcap_messages", 4e6, "messages", "messages in one MCAP recording"),
    # Plausibility of physical numbers read from files (not sizes): a value outside its range is an error naming the
    # file and the field, never a run that rejects every press or a map that overflows.
    Limit("length_m", 100, "m", "largest magnitude of a position or length read from a file: a recorded pose's "
          "coordinates, a haptic material's origin and cell"),
    Limit("length_min_m", 1e-6, "m", "smallest cell read from a file (a haptic material's cell_size_m), and the "
          "side of the smallest sensel; a lower bound: a smaller value allows smaller"),
    Limit("sensel_area_m2", 1e-2, "m^2", "largest sensel area of a recorded taxel frame"),
    Limit("time_s", 1e10, "s", "largest magnitude of a time stamp read from a recording"),
)}


def _overrides() -> dict[str, float]:
    text = os.environ.get(ENV, "").strip()
    out: dict[str, float] = {}
    for part in filter(None, (p.strip() for p in text.split(","))):
        name, sep, value = part.partition("=")
        out[name.strip()] = _parse(name.strip(), value.strip() if sep else "", f"{ENV}")
    return out


def _parse(name: str, value: str, where: str) -> float:
    if name not in LIMITS:
        raise ValidationError(f"{where}: unknown limit {name!r}; known limits: {', '.join(LIMITS)} "
                              "(see docs/limits.md)")
    try:
        v = float(value)
    except ValueError:
        raise ValidationError(f"{where}: limit {name} needs a number, got {value[:40]!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise ValidationError(f"{where}: limit {name} must be a finite number > 0, got {value[:40]!r}")
    return v


def limit(name: str) -> float:
    """The limit in force: ``PALPATE_LIMITS`` if it sets ``name``, else the default."""
    return _overrides().get(name, LIMITS[name].default)


def set_limit(assignment: str) -> None:
    """Apply ``NAME=VALUE`` (``palpate --limit``) to this process and the processes it starts."""
    name, sep, value = assignment.partition("=")
    v = _parse(name.strip(), value.strip() if sep else "", "--limit")
    current = {**_overrides(), name.strip(): v}
    os.environ[ENV] = ",".join(f"{k}={val:g}" for k, val in current.items())


def exceeded(name: str, what: str, value: float) -> ValidationError:
    """The error for ``what`` (naming the file and key) being ``value`` units, over the limit ``name``."""
    lim = LIMITS[name]
    return ValidationError(f"{what} is {_number(value)} {lim.unit}, over the limit {name} = {_number(limit(name))} "
                           f"{lim.unit} (raise it with palpate --limit {name}=N or {ENV}={name}=N; see docs/limits.md)")


def _number(v: float) -> str:
    return str(int(v)) if math.isfinite(v) and float(v).is_integer() and abs(v) < 1e15 else f"{v:.4g}"


def implausible(what: str, value: float, lo: float, hi: float, unit: str, *names: str) -> ValidationError:
    """The error for ``what`` (naming the file and field) being ``value`` ``unit``, outside [lo, hi], the range the
    limits ``names`` set."""
    raised = " or ".join(f"palpate --limit {n}=N" for n in names)
    return ValidationError(f"{what} = {_number(value)} {unit} is outside the plausible range {_number(lo)} to "
                           f"{_number(hi)} {unit} (limit {', '.join(names)}; change it with {raised}; "
                           "see docs/limits.md)")


def check(name: str, what: str, value: float) -> None:
    """Raise :func:`exceeded` when ``value`` is over the limit ``name`` (``MB`` limits take bytes)."""
    scale = 1e6 if LIMITS[name].unit == "MB" else 1.0
    if value > limit(name) * scale:
        raise exceeded(name, what, value / scale)
