"""Bounded reading of the files a user gives palpate: regular files only, sizes checked before reading, and every
problem a ValidationError of one line naming the file (and line or key).

A path that names a folder, a device (``/dev/zero``), a pipe or a socket is refused before a byte is read: a
symlink to ``/dev/zero`` given as a memory would otherwise be read until memory runs out. JSON documents are
checked for nesting depth and duplicate keys (which Python's json module silently resolves as "last wins"), and
never echoed whole into an error.
"""

from __future__ import annotations

import base64
import contextlib
import errno
import json
import math
import os
import stat
import tomllib
from array import array
from functools import lru_cache, wraps
from pathlib import Path

import numpy as np

from palpate.core import limits
from palpate.core.errors import ValidationError

#: Characters of a value shown in an error message; a file's value may be megabytes long.
BRIEF = 60


def brief(value, n: int = BRIEF) -> str:
    """``repr(value)`` cut to ``n`` characters, for error messages about values read from files."""
    text = repr(value)
    return text if len(text) <= n else f"{text[: n - 3]}..."


def named(exc: OSError, path) -> OSError:
    """``exc`` naming ``path`` when it names no file (a ``write`` that fills the disk says only "No space left on
    device"); the command line shows it as ``path: reason``."""
    if exc.filename is not None:
        return exc
    out = OSError(exc.errno, exc.strerror or str(exc), str(path))
    out.__cause__ = exc.__cause__
    return out


@contextlib.contextmanager
def writing(path):
    """Around the writing of ``path``: an OSError that names no file is raised again naming it."""
    try:
        yield
    except OSError as exc:
        if exc.filename is not None:
            raise
        raise named(exc, path) from None


def write_text(path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` whole or not at all; an I/O error names the file.

    The text goes to a hidden file beside ``path`` that then replaces it, so a process killed mid-write leaves
    the old file (or none), never a truncated one: a sweep takes a run with a readable summary.json as finished.
    """
    p = Path(path)
    tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp")
    with writing(path):
        try:
            tmp.unlink(missing_ok=True)  # a leftover (or a symlink planted there) is never written through
            tmp.write_text(text, encoding="utf-8")
            os.replace(tmp, p)
        except BaseException as exc:
            with contextlib.suppress(OSError):
                tmp.unlink()
            if isinstance(exc, OSError) and exc.filename == str(tmp):  # name the file the user knows
                raise OSError(exc.errno, exc.strerror or str(exc), str(p)) from None
            raise


def _os_error(path: Path, what: str, exc: OSError) -> ValidationError:
    reason = {errno.ENOENT: "not found", errno.EACCES: "permission denied", errno.EISDIR: "it is a folder",
              errno.ELOOP: "a symlink loop", errno.ENOTDIR: "a part of the path is not a folder"}
    return ValidationError(f"{path}: cannot read {what}: {reason.get(exc.errno, exc.strerror or str(exc))}")


def regular_file(path: str | Path, what: str) -> Path:
    """``path`` if it names a regular file (after symlinks); ValidationError otherwise (missing, a folder, a
    device, a pipe)."""
    p = Path(path)
    try:
        st = os.stat(p)
    except OSError as exc:
        raise _os_error(p, what, exc) from None
    if not stat.S_ISREG(st.st_mode):
        kind = "a folder" if stat.S_ISDIR(st.st_mode) else "a device, pipe or socket"
        raise ValidationError(f"{p}: {what}: is {kind}, not a regular file")
    return p


def _open_regular(p: Path, what: str):
    """A binary file object on ``p``, opened without blocking (a pipe cannot stall it) and checked with ``fstat``
    on the open descriptor (a file swapped for a device after a check is still refused)."""
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise _os_error(p, what, exc) from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        kind = "a folder" if stat.S_ISDIR(st.st_mode) else "a device, pipe or socket"
        raise ValidationError(f"{p}: {what}: is {kind}, not a regular file")
    return os.fdopen(fd, "rb"), st.st_size


def read_bytes(path: str | Path, what: str, limit: str = "text_mb") -> bytes:
    """The whole content of a regular file no larger than the limit ``limit`` (an ``MB`` limit); at most the limit
    plus one byte is read, so a file that grows while being read cannot exceed it either."""
    p = Path(path)
    f, size = _open_regular(p, what)
    with f:
        limits.check(limit, f"{p}: {what}: file size", size)
        try:
            data = f.read(int(limits.limit(limit) * 1e6) + 1)
        except OSError as exc:
            raise _os_error(p, what, exc) from None
    limits.check(limit, f"{p}: {what}: file size", len(data))
    return data


def read_bytes_head(path: str | Path, what: str, n: int) -> bytes:
    """The first ``n`` bytes (fewer if the file is shorter) of a regular file."""
    p = Path(path)
    f, _ = _open_regular(p, what)
    with f:
        try:
            return f.read(n)
        except OSError as exc:
            raise _os_error(p, what, exc) from None


def read_text(path: str | Path, what: str, limit: str = "text_mb", encoding: str = "utf-8") -> str:
    """A bounded regular text file decoded as ``encoding``; an undecodable byte is an error naming its offset."""
    data = read_bytes(path, what, limit)
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as exc:
        raise ValidationError(f"{path}: not UTF-8 text ({what}; byte {exc.start}: {exc.reason}); save it as "
                              "UTF-8") from None


class _DuplicateKey(ValueError):
    def __init__(self, key: str):
        super().__init__(key)
        self.key = key


def _pairs(pairs: list[tuple[str, object]]) -> dict:
    out = dict(pairs)
    if len(out) != len(pairs):
        seen: set[str] = set()
        for k, _ in pairs:
            if k in seen:
                raise _DuplicateKey(k)
            seen.add(k)
    return out


def _no_constant(name: str):
    raise ValueError(f"{name} is not a number JSON allows (expected finite numbers only)")


def parse_json(text: str, source: str, what: str) -> object:
    """Decode a JSON document; ValidationError naming ``source`` (and the line) for anything a file can do wrong:
    invalid JSON, duplicate keys, NaN/Infinity, numbers of more than 4300 digits, nesting over ``json_depth``."""
    try:
        doc = json.loads(text, object_pairs_hook=_pairs, parse_constant=_no_constant)
    except json.JSONDecodeError as exc:
        raise ValidationError(f"{source}:{exc.lineno}: not valid JSON ({what}): {exc.msg}") from None
    except _DuplicateKey as exc:
        raise ValidationError(f"{source}: {what}: key {brief(exc.key)} appears twice in one object (which one "
                              "is meant?)") from None
    except RecursionError:
        raise limits.exceeded("json_depth", f"{source}: {what}: nesting depth", float("inf")) from None
    except ValueError as exc:  # Python's limit on integer digits, or parse_constant
        raise ValidationError(f"{source}: {what}: {str(exc)[:120]}") from None
    try:
        depth = json_depth(doc)
    except OverflowError:
        raise ValidationError(f"{source}: {what}: a number too large for a float (expected finite numbers only)") \
            from None
    limits.check("json_depth", f"{source}: {what}: nesting depth", depth)
    return doc


def json_depth(doc: object) -> int:
    """Nesting depth of a decoded JSON value (a scalar is 0), computed without recursion; OverflowError at a number
    that decoded to an infinite float (its digits too large for one). A list of numbers only is taken in one C loop
    (an array of doubles: no Python step per number, and no more memory than its numbers; strings, nulls, numbers
    past a double and nested values fall back to walking the list)."""
    deepest, stack = 0, [(doc, 0)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, dict):
            children = node.values()
        elif isinstance(node, list):
            try:
                numbers = array("d", node)
            except (TypeError, OverflowError):
                children = node
            else:
                # a sum of finite numbers is finite unless they are huge: only then are they looked at one by one
                if not math.isfinite(sum(numbers)) and not all(map(math.isfinite, numbers)):
                    raise OverflowError("a number too large for a float")
                deepest = max(deepest, depth + 1)
                continue
        else:
            if isinstance(node, float) and not math.isfinite(node):
                raise OverflowError("a number too large for a float")
            continue
        deepest = max(deepest, depth + 1)
        stack.extend((c, depth + 1) for c in children if isinstance(c, (dict, list, float)))
    return deepest


def read_json(path: str | Path, what: str) -> object:
    """A bounded JSON file, decoded with :func:`parse_json`."""
    return parse_json(read_text(path, what), str(path), what)


def read_toml(path: str | Path, what: str) -> dict:
    """A bounded TOML file (UTF-8, as TOML requires); ValidationError naming the file for anything wrong."""
    text = read_text(path, what)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValidationError(f"{path}: not valid TOML ({what}): {exc}") from None
    except RecursionError:
        raise ValidationError(f"{path}: {what}: nesting too deep to read") from None
    except ValueError as exc:  # Python's limit on integer digits
        raise ValidationError(f"{path}: {what}: {str(exc)[:120]}") from None


def number_array(value, where: str, ndim: int, max_size: int | None = None) -> np.ndarray:
    """``value`` (read from a file) as a float array of ``ndim`` dimensions, non-empty, finite and at most
    ``max_size`` numbers when given; else a ValidationError naming ``where`` (e.g. "FILE: key")."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValidationError(f"{where} must be numbers") from None
    size = f"1 to {max_size}" if max_size is not None else "at least one"
    if (arr.ndim != ndim or arr.size == 0 or (max_size is not None and arr.size > max_size)
            or not np.all(np.isfinite(arr))):
        raise ValidationError(f"{where} must be a {ndim}-D array of {size} finite numbers")
    return arr


#: The ``packed`` tag of an array of decimals stored as integers (see :func:`pack_decimals`).
PACKED = "fixed-point"
_PACKED_KEYS = {"packed", "dtype", "shape", "divisor", "base64"}
_PACKED_DTYPES = ("<i2", "<i4", "<i8")


def pack_decimals(values, decimals: int) -> dict:
    """``values`` rounded to ``decimals`` places as a JSON object: the integers value x 10^decimals, little-endian
    in base64, with their dtype, shape and divisor: less text than a list of the same numbers, read in milliseconds
    where a JSON list of 10^5 numbers takes ~0.1 s; :func:`decimal_array` gives back exactly the floats the list's
    decimals would parse to (an integer over a power of ten, correctly rounded)."""
    arr = np.rint(np.asarray(values, dtype=float) * 10**decimals)
    if not (0 <= decimals <= 12 and np.all(np.isfinite(arr)) and np.all(np.abs(arr) < 2**53)):
        raise ValidationError("pack_decimals: finite values and 0-12 decimals, no more than 15 digits in all")
    big = float(np.max(np.abs(arr))) if arr.size else 0.0
    dtype = next(d for d, bits in zip(_PACKED_DTYPES, (15, 31, 63), strict=True) if big < 2**bits)
    return {"packed": PACKED, "dtype": dtype, "shape": list(arr.shape), "divisor": 10**decimals,
            "base64": base64.b64encode(arr.astype(dtype).tobytes()).decode("ascii")}


def decimal_array(value, where: str, ndim: int, max_size: int | None = None) -> np.ndarray:
    """:func:`number_array` of a list of numbers or of a :func:`pack_decimals` object, checked alike; a packed
    object's tags, shape and length are checked before anything is decoded."""
    if not isinstance(value, dict):
        return number_array(value, where, ndim, max_size)
    shape, divisor, dtype, text = (value.get(k) for k in ("shape", "divisor", "dtype", "base64"))
    if (set(value) != _PACKED_KEYS or value["packed"] != PACKED or dtype not in _PACKED_DTYPES
            or not isinstance(text, str) or not isinstance(shape, list) or len(shape) != ndim
            or not all(type(n) is int and 0 < n for n in shape) or type(divisor) is not int
            or divisor not in {10**k for k in range(13)}):
        raise ValidationError(f"{where} must be a list of numbers or a packed array ({sorted(_PACKED_KEYS)}, "
                              f"packed {PACKED!r}, dtype one of {_PACKED_DTYPES}, a {ndim}-D shape of positive "
                              "integers, a power-of-ten divisor)")
    size = math.prod(shape)
    if max_size is not None and size > max_size:
        raise ValidationError(f"{where} must hold at most {max_size} numbers, its shape {shape} holds {size}")
    nbytes = size * np.dtype(dtype).itemsize
    if len(text) != 4 * math.ceil(nbytes / 3):
        raise ValidationError(f"{where}: {len(text)} base64 characters for {nbytes} bytes of {shape} {dtype}")
    try:
        raw = base64.b64decode(text, validate=True)
    except ValueError:
        raise ValidationError(f"{where}: not base64") from None
    if len(raw) != nbytes:
        raise ValidationError(f"{where}: {len(raw)} bytes for {nbytes} bytes of {shape} {dtype}")
    return np.frombuffer(raw, dtype=dtype).reshape(shape).astype(float) / divisor


def per_file_version(read, maxsize: int = 4):
    """``read(path)`` made to read each version of a file once: its answers are kept by the file's path, size and
    modification time (ns), so a file written again is read again. Only for readers whose answers cannot be changed
    (frozen dataclasses of tuples, read-only arrays): every caller gets the same object. A path that cannot be
    examined goes to ``read`` itself, which says what is wrong with it."""

    @lru_cache(maxsize=maxsize)
    def cached(path: str, size: int, mtime_ns: int):
        return read(Path(path))

    @wraps(read)
    def load(path):
        try:
            st = Path(path).stat()
        except OSError:
            return read(Path(path))
        return cached(str(path), st.st_size, st.st_mtime_ns)

    return load
