"""Names from files are names, never paths.

An object, scenario or material name read from a scenario or a recording becomes part of a file name
(``maps/<object>.npz``, ``runs/<scenario>``). :func:`check_name` refuses, at load, a name that could not be a
file name on any system; :func:`file_stem` maps any name to a safe stem (what is written); :func:`inside` is the
last check before anything is written: the path must lie inside the output folder, also after symlinks.
"""

from __future__ import annotations

import os
import unicodedata
from pathlib import Path

from palpate.core.errors import ValidationError

#: Longest name accepted (and longest file stem written), characters.
MAX_NAME = 100
#: Punctuation a file stem may keep; every other character that is not a letter or digit becomes ``_``.
STEM_PUNCTUATION = "-_.+"


def check_name(name: str, where: str) -> str:
    """``name`` if it is usable as a name that becomes a file name: 1..MAX_NAME printable characters, no path
    separator, not starting with a dot or space. ValidationError naming ``where`` (file and key) otherwise."""
    if not isinstance(name, str) or not name.strip():
        raise ValidationError(f"{where}: a name must be a non-empty string")
    bad = sorted({c for c in name if c in "/\\" or unicodedata.category(c)[0] in "CZ" and c != " "})
    if bad or len(name) > MAX_NAME or name[0] in ". " or name[-1] == " ":
        raise ValidationError(f"{where}: {name[:MAX_NAME]!r} cannot be a name: names become file names, so use at "
                              f"most {MAX_NAME} letters, digits, spaces and -_.+() (no / or \\, not starting with a "
                              "dot or a space)")
    return name


def file_stem(name: str) -> str:
    """A safe file stem for ``name``: letters, digits and ``-_.+`` kept, anything else ``_``, no leading dot, at
    most MAX_NAME characters. Different names can share a stem: callers that write one file per name check that
    (:func:`unique_stems`)."""
    stem = "".join(c if c.isalnum() and c.isascii() or c in STEM_PUNCTUATION else "_" for c in str(name))
    stem = stem[:MAX_NAME]
    if not stem or stem.startswith("."):
        stem = "_" + stem[: MAX_NAME - 1]
    return stem


def unique_stems(names, where: str) -> dict[str, str]:
    """name -> file stem for every name; ValidationError when two names would write the same files."""
    out: dict[str, str] = {}
    by_stem: dict[str, str] = {}
    for name in names:
        stem = file_stem(name)
        if stem in by_stem and by_stem[stem] != name:
            raise ValidationError(f"{where}: names {by_stem[stem]!r} and {name!r} would both be written as "
                                  f"{stem!r}; rename one")
        by_stem[stem] = name
        out[name] = stem
    return out


def inside(root: str | Path, path: str | Path) -> Path:
    """``path`` if it lies inside the folder ``root`` once both are resolved (symlinks followed); ValidationError
    otherwise. Every file palpate writes for a run, replay or sweep goes through this."""
    base = Path(os.path.realpath(root))
    target = Path(os.path.realpath(path))
    if target != base and base not in target.parents:
        raise ValidationError(f"{path}: refusing to write outside the output folder {root}")
    return Path(path)
