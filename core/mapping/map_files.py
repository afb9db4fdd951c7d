"""Map files: probabilities and the explored mask in an NPZ (no pickled objects), metadata in a JSON sidecar.

Both are validated on read; every error names the file and the key.
"""

from __future__ import annotations

import json
import math
import zipfile
import zlib
from pathlib import Path

import numpy as np

from palpate.core import files, limits
from palpate.core.errors import ValidationError
from palpate.core.files import brief
from palpate.core.mapping.geometry import check_finite_tuple, check_positive
from palpate.core.mapping.probability import check_base, first_index

FORMAT_NAME = "palpate.map"
FORMAT_VERSION = 1
# Files written here are normalised to float64 precision; a file further off than this was edited.
SUM_TOL_FILE = 1e-6


def write_map_files(path, p: np.ndarray, explored: np.ndarray, meta: dict) -> tuple[Path, Path]:
    """Write arrays to ``path`` (.npz) and ``meta`` (plus format and version) to the same name with .json.

    Returns:
        (npz path, json path).
    """
    npz = Path(path)
    if npz.suffix != ".npz":
        raise ValidationError(f"map file must end in .npz (metadata goes beside it as .json), got {npz}")
    sidecar = npz.with_suffix(".json")
    with files.writing(npz):
        np.savez_compressed(npz, probabilities=p, explored=explored)
    files.write_text(sidecar, json.dumps({"format": FORMAT_NAME, "version": FORMAT_VERSION, **meta}, indent=2) + "\n")
    return npz, sidecar


def read_map_files(path, kind: str) -> tuple[dict, np.ndarray, np.ndarray]:
    """Read and validate an NPZ + JSON map pair; errors name the file and the key."""
    npz = Path(path)
    sidecar = npz.with_suffix(".json")
    if npz.suffix != ".npz":
        raise ValidationError(f"map file must end in .npz, got {npz}")
    for f in (npz, sidecar):
        if not f.exists():
            raise ValidationError(f"map file {f} does not exist (a map is an .npz with a .json beside it)")
    meta = files.read_json(sidecar, "map sidecar")
    if not isinstance(meta, dict):
        raise ValidationError(f"{sidecar}: expected a JSON object at top level, got {type(meta).__name__}")
    required = ("format", "version", "kind", "materials", "shape", "cell_size_m", "origin_m", "base", "p_min")
    for key in required:
        if key not in meta:
            raise ValidationError(f"{sidecar}: missing key {key!r}")
    if meta["format"] != FORMAT_NAME:
        raise ValidationError(f"{sidecar}: key 'format' must be {FORMAT_NAME!r}, got {brief(meta['format'])}")
    if meta["version"] != FORMAT_VERSION:
        raise ValidationError(f"{sidecar}: key 'version' is {brief(meta['version'])}; this palpate reads version "
                              f"{FORMAT_VERSION}")
    if meta["kind"] != kind:
        raise ValidationError(f"{sidecar}: key 'kind' is {brief(meta['kind'])}, expected {kind!r}")
    arrays = read_npz(npz, {"probabilities": ("<f8", "<f4"), "explored": ("|b1",)})
    p, explored = arrays["probabilities"], arrays["explored"]
    if p.dtype.kind != "f":
        raise ValidationError(f"{npz}: 'probabilities' must be a float array, got {p.dtype}")
    if explored.dtype != bool:
        raise ValidationError(f"{npz}: 'explored' must be a boolean array, got {explored.dtype}")
    if not np.all(np.isfinite(p)):
        raise ValidationError(f"{npz}: 'probabilities' contains NaN or infinite values")
    if (p < 0).any() or (p > 1).any():
        raise ValidationError(f"{npz}: 'probabilities' has values outside [0, 1]")
    if p.size and (np.abs(p.sum(axis=-1) - 1.0) > SUM_TOL_FILE).any():
        idx = first_index(np.abs(p.sum(axis=-1) - 1.0) > SUM_TOL_FILE)
        raise ValidationError(f"{npz}: 'probabilities' cell {idx} sums to {p[idx].sum():.9g}, expected 1")
    if p.shape[:-1] != explored.shape:
        raise ValidationError(f"{npz}: 'explored' shape {explored.shape} does not match 'probabilities' "
                              f"{p.shape}")
    if not isinstance(meta["materials"], list) or p.shape[-1] != len(meta["materials"]):
        raise ValidationError(f"{sidecar}: key 'materials' must list the {p.shape[-1]} materials of {npz}")
    return meta, p, explored


def read_npz(path: Path, expected: dict[str, tuple[str, ...]]) -> dict[str, np.ndarray]:
    """The arrays of an NPZ file holding exactly the arrays ``expected`` (name -> allowed dtype strings).

    Sizes are checked before anything is decoded: the file's size, and each array's size as its ``.npy`` header
    declares it (shape x item size), against the limit ``npz_mb``; an array is then read by numpy, which reads no
    more than its header declares, so a member that inflates to gigabytes is never inflated. Never unpickles.
    """
    files.regular_file(path, "map NPZ")
    limits.check("npz_mb", f"{path}: file size", path.stat().st_size)
    out = {}
    try:
        with zipfile.ZipFile(path) as zf:
            names = {n.removesuffix(".npy"): n for n in zf.namelist()}
            missing = sorted(set(expected) - set(names))
            extra = sorted(set(names) - set(expected))
            if missing:
                raise ValidationError(f"{path}: missing array {missing[0]!r} (has {brief(sorted(names))})")
            if extra:
                raise ValidationError(f"{path}: unexpected arrays {brief(extra)}")
            for name, member in names.items():
                with zf.open(member) as f:
                    version = np.lib.format.read_magic(f)
                    reader = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                              else np.lib.format.read_array_header_2_0)
                    shape, _, dtype = reader(f)
                if dtype.str not in expected[name]:
                    kinds = " or ".join("boolean" if d == "|b1" else f"float{8 * int(d[-1])}" for d in expected[name])
                    raise ValidationError(f"{path}: array {name!r} must be a {kinds} array, got {dtype}")
                limits.check("npz_mb", f"{path}: array {name!r} of shape {list(shape)}: decoded size",
                             math.prod(shape) * dtype.itemsize)
                with zf.open(member) as f:
                    out[name] = np.lib.format.read_array(f, allow_pickle=False)
    except ValidationError:
        raise
    except (OSError, ValueError, zipfile.BadZipFile, EOFError, RuntimeError, zlib.error) as exc:
        raise ValidationError(f"{path}: not a readable NPZ file ({brief(str(exc), 120)})") from None
    return out


def meta_value(meta: dict, key: str, sidecar: Path, check):
    try:
        return check(meta[key])
    except (ValidationError, TypeError, ValueError) as exc:
        raise ValidationError(f"{sidecar}: key {key!r}: {exc}") from None


def construct(sidecar: Path, build):
    """Run a constructor on loaded metadata so that its own checks (e.g. p_min < 1/M) name the file too."""
    try:
        return build()
    except ValidationError as exc:
        if str(exc).startswith(str(sidecar)):
            raise
        raise ValidationError(f"{sidecar}: {exc}") from None


def common_meta(meta: dict, sidecar: Path) -> dict:
    """The constructor keywords every map kind reads from its JSON sidecar, each validated."""
    return {
        "origin": meta_value(meta, "origin_m", sidecar, lambda v: check_finite_tuple(v, 2, "origin")),
        "cell_size": meta_value(meta, "cell_size_m", sidecar, lambda v: check_positive(v, "cell_size")),
        "p_min": meta_value(meta, "p_min", sidecar, check_p_min),
        "base": meta_value(meta, "base", sidecar, check_base),
    }


def check_p_min(value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValidationError(f"p_min must be a number, got {value!r}")
    return float(value)
