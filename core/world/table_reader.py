"""Typed, validated reading of TOML tables (scenarios, sweeps, actuator options): every error names the file, the
key path and what was expected."""

from __future__ import annotations

import difflib
import math
from pathlib import Path
from typing import Any

from palpate.core.errors import ValidationError
from palpate.core.files import brief

#: Default meaning "this key is required".
REQUIRED = object()


class TableReader:
    """Typed access to a TOML table that records the key path for error messages.

    Every getter records the key as used; :meth:`finish` refuses the keys nobody asked for, so a misspelt key is
    an error, never silently ignored. Errors read ``<file>: <key path>: <what was expected>``.
    """

    def __init__(self, file: str, table: dict, path: str):
        self.file, self.table, self.path = file, table, path
        self.used: set[str] = set()

    def err(self, key: str, msg: str) -> ValidationError:
        where = f"{self.path}.{key}" if self.path else key
        return ValidationError(f"{self.file}: {where}: {msg}")

    def get(self, key: str, kind: type | tuple, default: Any = REQUIRED) -> Any:
        self.used.add(key)
        if key not in self.table:
            if default is REQUIRED:
                raise self.err(key, "missing (required)")
            return default
        value = self.table[key]
        kinds = kind if isinstance(kind, tuple) else (kind,)
        if float in kinds and isinstance(value, int) and not isinstance(value, bool):
            try:
                value = float(value)
            except OverflowError:
                raise self.err(key, f"{brief(value)} is too large for a number") from None
        if isinstance(value, bool) and bool not in kinds:
            raise self.err(key, f"expected {_kind_name(kinds)}, got a boolean")
        if not isinstance(value, kinds):
            raise self.err(key, f"expected {_kind_name(kinds)}, got {type(value).__name__} {brief(value)}")
        return value

    def number(self, key: str, default: Any = REQUIRED, *, lo: float | None = None, hi: float | None = None,
               lo_open: bool = False) -> float | None:
        """A finite number within [lo, hi] (``lo_open``: > lo); ``default`` as given when the key is absent (None
        only for an optional key whose default is None)."""
        value = self.get(key, float, default)
        if value is None or value is default and default is not REQUIRED:
            return value
        if not math.isfinite(value):
            raise self.err(key, f"must be a finite number, got {value}")
        if lo is not None and (value < lo or (lo_open and value == lo)):
            raise self.err(key, f"must be {'>' if lo_open else '>='} {lo}, got {value}")
        if hi is not None and value > hi:
            raise self.err(key, f"must be <= {hi}, got {value}")
        return value

    def integer(self, key: str, default: Any = REQUIRED, *, lo: int | None = None, hi: int | None = None) -> int | None:
        """An integer within [lo, hi]; ``default`` as given when the key is absent (None only for an optional key
        whose default is None)."""
        value = self.get(key, int, default)
        if value is None:  # an optional key left out (default None): nothing to bound
            return value
        if lo is not None and value < lo:
            raise self.err(key, f"must be >= {lo}, got {brief(value)}")
        if hi is not None and value > hi:
            raise self.err(key, f"must be <= {hi}, got {brief(value)}")
        return value

    def choice(self, key: str, choices: tuple[str, ...], default: Any = REQUIRED) -> str:
        value = self.get(key, str, default)
        if value not in choices:
            raise self.err(key, f"must be one of {', '.join(choices)}; got {brief(value)}")
        return value

    def numbers(self, key: str, count: int | tuple[int, ...], default: Any = REQUIRED, *,
                positive: bool = False, limit: float | None = None) -> tuple[float, ...]:
        """``count`` finite numbers (or one of several counts); ``positive``: each > 0; ``limit``: each of
        magnitude at most ``limit``."""
        value = self.get(key, list, default)
        if value is default and default is not REQUIRED:
            return value
        counts = count if isinstance(count, tuple) else (count,)
        if len(value) not in counts or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                               for v in value):
            raise self.err(key, f"expected {' or '.join(map(str, counts))} numbers, got {brief(value)}")
        try:
            out = tuple(float(v) for v in value)
        except OverflowError:
            raise self.err(key, f"numbers must be finite, got {brief(value)}") from None
        if not all(math.isfinite(v) for v in out):
            raise self.err(key, f"numbers must be finite, got {brief(value)}")
        if positive and any(v <= 0 for v in out):
            raise self.err(key, f"values must be > 0, got {brief(value)}")
        if limit is not None and any(abs(v) > limit for v in out):
            raise self.err(key, f"values must be at most {limit:g} in magnitude, got {brief(value)}")
        return out

    def sub(self, key: str, required: bool = False) -> TableReader:
        value = self.get(key, dict, REQUIRED if required else {})
        return TableReader(self.file, value, f"{self.path}.{key}" if self.path else key)

    def subs(self, key: str) -> list[TableReader]:
        value = self.get(key, list, [])
        out = []
        for i, item in enumerate(value):
            where = f"{self.path}.{key}[{i}]" if self.path else f"{key}[{i}]"
            if not isinstance(item, dict):
                raise ValidationError(f"{self.file}: {where}: expected a table, got {brief(item)}")
            out.append(TableReader(self.file, item, where))
        return out

    def finish(self) -> None:
        extra = sorted(set(self.table) - self.used)
        if extra:
            close = difflib.get_close_matches(extra[0], sorted(self.used), n=1, cutoff=0.6)
            hint = f"did you mean {close[0]!r}? " if close else ""
            raise self.err(extra[0], f"unknown key ({hint}known keys here: {', '.join(sorted(self.used))})")


def _kind_name(kinds: tuple) -> str:
    names = {str: "a string", float: "a number", int: "an integer", bool: "true or false", list: "an array",
             dict: "a table"}
    return " or ".join(names.get(k, k.__name__) for k in kinds)


def resolve_path(base: Path, value: str) -> Path:
    """A path from a file, relative to the file's folder (or its parent), or as given when it exists."""
    p = Path(value)
    if p.is_absolute() or p.exists():
        return p
    return base / p if (base / p).exists() else base.parent / p
