"""Map files: probabilities and the explored mask in an NPZ (no pickled objects), metadata in a JSON sidecar.

Both are validated on read; every error names the file and the key.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
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
    np.savez_compressed(npz, probabilities=p, explored=explored)
    sidecar.write_text(json.dumps({"format": FORMAT_NAME, "version": FORMAT_VERSION, **meta}, indent=2) + "\n")
    return npz, sidecar


def read_map_files(path, kind: str) -> tuple[dict, np.ndarray, np.ndarray]:
    """Read and validate an NPZ + JSON map pair; errors name the file and the key."""
    npz = Path(path)
    sidecar = npz.with_suffix(".json")
    if npz.suffix != ".npz":
        raise ValidationError(f"map file must end in .npz, got {npz}")
    for f in (npz, sidecar):
        if not f.is_file():
            raise ValidationError(f"map file {f} does not exist (a map is an .npz with a .json beside it)")
    try:
        meta = json.loads(sidecar.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValidationError(f"{sidecar}: not valid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise ValidationError(f"{sidecar}: expected a JSON object at top level, got {type(meta).__name__}")
    required = ("format", "version", "kind", "materials", "shape", "cell_size_m", "origin_m", "base", "p_min")
    for key in required:
        if key not in meta:
            raise ValidationError(f"{sidecar}: missing key {key!r}")
    if meta["format"] != FORMAT_NAME:
        raise ValidationError(f"{sidecar}: key 'format' must be {FORMAT_NAME!r}, got {meta['format']!r}")
    if meta["version"] != FORMAT_VERSION:
        raise ValidationError(f"{sidecar}: key 'version' is {meta['version']!r}; this palpate reads version "
                              f"{FORMAT_VERSION}")
    if meta["kind"] != kind:
        raise ValidationError(f"{sidecar}: key 'kind' is {meta['kind']!r}, expected {kind!r}")
    try:
        arrays = np.load(npz, allow_pickle=False)
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise ValidationError(f"{npz}: not a readable NPZ file ({exc})") from None
    with arrays:
        for key in ("probabilities", "explored"):
            if key not in arrays.files:
                raise ValidationError(f"{npz}: missing array {key!r} (has {arrays.files})")
        extra = sorted(set(arrays.files) - {"probabilities", "explored"})
        if extra:
            raise ValidationError(f"{npz}: unexpected arrays {extra}")
        try:
            p = arrays["probabilities"]
            explored = arrays["explored"]
        except (ValueError, OSError, zipfile.BadZipFile, EOFError) as exc:
            raise ValidationError(f"{npz}: cannot read arrays ({exc})") from None
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
