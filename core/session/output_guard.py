"""Outputs never destroy inputs or old results silently.

A run, replay or sweep writes into a folder that is new, empty, or already holds a palpate output of the same
kind; it replaces an earlier one only when asked (``force``, the commands' ``--force``), and then removes exactly
the files that kind writes, so an old run's maps or figures never mix with a new summary. A folder holding
anything else is never written into. A single output file (a recording, a memory) is never an input of the same
command and never replaces an existing file without ``force``. An output folder or file that is itself a symbolic
link is refused, with or without ``force``: what palpate writes lands where the user named it, never in a link's
target.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

from palpate.core.errors import ValidationError

#: Written first into every output folder, so that even a killed run's folder is recognised as one.
MARKER = ".palpate-output.json"
#: What each kind of output folder holds (removed by ``force`` before the new output is written).
OUTPUTS = {
    "run": ("summary.json", "memory.json", "memory_layers.json", "maps", "figures", "haptic_materials"),
    "replay": ("summary.json", "maps", "figures"),
    "sweep": ("sweep.csv", "sweep.json", "runs"),
}
#: Formats of the summaries written before the marker existed.
_SUMMARY_KINDS = {"palpate-run-summary": "run", "palpate-replay-summary": "replay", "palpate-sweep": "sweep"}


def folder_kind(folder: Path) -> str | None:
    """The kind of palpate output a folder holds ("run", "replay", "sweep"), or None."""
    for name, key in ((MARKER, "kind"), ("summary.json", "format"), ("sweep.json", "format")):
        path = folder / name
        try:
            if path.is_file() and path.stat().st_size < 1_000_000:
                doc = json.loads(path.read_text(encoding="utf-8"))
                value = doc.get(key) if isinstance(doc, dict) else None
                kind = value if key == "kind" else _SUMMARY_KINDS.get(value)
                if kind in OUTPUTS:
                    return kind
        except (OSError, ValueError):
            continue
    # a sweep folder from before the marker, or one killed before its table: runs/<variant>/variant.json
    if (folder / ".sweep.lock").exists() or next((folder / "runs").glob("*/variant.json"), None) is not None:
        return "sweep"
    return None


def _same(a: Path, b: Path) -> bool:
    return os.path.realpath(a) == os.path.realpath(b)


def _within(path: Path, folder: Path) -> bool:
    p, f = Path(os.path.realpath(path)), Path(os.path.realpath(folder))
    return p == f or f in p.parents


def _extras(folder: Path) -> list[Path]:
    """Further files an earlier output recorded in its marker as its own (e.g. a run's ``--record`` inside it)."""
    try:
        doc = json.loads((folder / MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return []
    names = doc.get("extra", []) if isinstance(doc, dict) else []
    out = []
    for name in names if isinstance(names, list) else []:
        if isinstance(name, str) and name and Path(name).name == name and name not in (".", ".."):
            out.append(folder / name)
    return out


def refuse_link(path: Path, option: str, what: str) -> None:
    """ValidationError when the output ``path`` itself is a symbolic link: what is written there would land in the
    link's target, somewhere the user did not name (a folder the link leads into, or a file it replaces)."""
    if path.is_symlink():
        try:
            target = os.readlink(path)
        except OSError:
            target = "?"
        raise ValidationError(f"{option} {path}: is a symbolic link (to {target}); palpate never writes an output "
                              f"through a link: give the real {what} or a new name")


def prepare_output_folder(out: str | Path, kind: str, *, force: bool = False, inputs=(), option: str = "--out",
                          extra=()) -> Path:
    """Make ``out`` ready for a new output of ``kind`` and mark it; ValidationError (one line) when it may not be.

    Args:
        out: the output folder.
        kind: "run", "replay" or "sweep".
        force: replace an earlier output of the same kind (its files, :data:`OUTPUTS`, and the further files its
            marker names, are removed first).
        inputs: paths this command reads; none of them may be removed.
        option: how the user named the folder, for messages.
        extra: further files of this output directly inside ``out`` (names), removed by a later ``force``.
    """
    folder = Path(out)
    refuse_link(folder, option, "folder")
    if folder.exists() and not folder.is_dir():
        raise ValidationError(f"{option} {folder}: is a file, not a folder; give a folder (new or empty)")
    if folder.is_dir() and any(folder.iterdir()):
        found = folder_kind(folder)
        if found is None:
            raise ValidationError(f"{option} {folder}: the folder is not empty and holds no palpate output; "
                                  "give a new or empty folder (palpate never deletes files it did not write)")
        if found != kind:
            raise ValidationError(f"{option} {folder}: holds a palpate {found}, not a {kind}; give another folder")
        if kind != "sweep":  # a sweep folder is resumed, never replaced by default
            if not force:
                raise ValidationError(f"{option} {folder}: already holds a palpate {kind}; add --force to replace "
                                      f"it, or give another folder")
            doomed = [p for p in [folder / name for name in OUTPUTS[kind]] + _extras(folder)
                      if p.exists() or p.is_symlink()]
            for path in inputs:
                if path is not None and any(_within(Path(path), d) for d in doomed):
                    raise ValidationError(f"{option} {folder}: --force would delete {path}, an input of this "
                                          "command; move it out or give another folder")
            for d in doomed:
                shutil.rmtree(d) if d.is_dir() and not d.is_symlink() else d.unlink()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        marker = folder / MARKER
        if marker.is_symlink():  # written anew, never through a link to a file elsewhere
            marker.unlink()
        marker.write_text(json.dumps({"kind": kind, "extra": list(extra)}) + "\n", encoding="utf-8")
    except OSError as exc:
        raise ValidationError(f"{option} {folder}: cannot write there: {exc.strerror or exc}") from None
    return folder


def check_output_file(path: str | Path, *, inputs=(), force: bool = False, option: str = "--out",
                      outputs: Path | None = None, kind: str | None = None) -> Path:
    """``path`` if a new file may be written there: not a folder, not one of ``inputs`` (even with ``force``),
    not an existing file unless ``force``, and not one of the files an output folder ``outputs`` of ``kind``
    holds. ValidationError (one line) otherwise."""
    p = Path(path)
    refuse_link(p, option, "file")
    if p.is_dir():
        raise ValidationError(f"{option} {p}: is a folder; give a file name")
    for src in inputs:
        if src is not None and Path(src).exists() and _same(p, Path(src)):
            raise ValidationError(f"{option} {p}: is an input of this command; writing it would destroy it")
    if outputs is not None and kind is not None:
        for name in OUTPUTS[kind]:
            if _within(p, Path(outputs) / name):
                raise ValidationError(f"{option} {p}: is a file this command writes into {outputs}; give another "
                                      "name")
    if (p.exists() or p.is_symlink()) and not force:
        raise ValidationError(f"{option} {p}: exists; add --force to overwrite it, or give another name")
    return p
