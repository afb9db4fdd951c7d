"""The image columns of the validity table as data: per rung, case and depth, the force error, the rms sensel error
as a share of the reference's peak, whether the asymmetry holds, and the active sensels, against the 3-D FE image
reference (:mod:`.image_measure`; models/image_validity.json, written by benchmarks/image_validity.py --write).

``auto`` reads it for presses whose material changes off the press axis within reach (:mod:`.choice`): there the
image matters, and a rung whose image fails the family is never chosen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.files import per_file_version
from palpate.core.world.resources import models_dir
from palpate.sim.validity.image_measure import ImageScore
from palpate.sim.validity.reference import read_document

IMAGE_TABLE_PATH = models_dir() / "image_validity.json"
FORMAT = "palpate-image-validity"
VERSION = 1
#: What a valid image is: rms sensel error at most this share of the peak, asymmetry of the right sign and within
#: 20% where the reference's exceeds 0.1, at every depth from MIN_DEPTH.
RMS_LIMIT = 0.10
MIN_DEPTH = 1e-3


@dataclass(frozen=True)
class ImageRow:
    """One rung on one case at one depth (see the module docstring)."""

    case: str
    family: str
    split: str
    rung: str
    depth: float
    force_error: float
    rms_share: float
    asymmetry_ok: bool
    active: int
    reference_active: int

    def to_dict(self) -> dict:
        """The row as the file writes it."""
        return dict(self.__dict__)


@dataclass(frozen=True)
class ImageTable:
    """The rows, and per (rung, family) the verdict over depths >= MIN_DEPTH."""

    rows: tuple[ImageRow, ...]

    def measures(self, family: str) -> bool:
        """Whether any rung was measured on ``family`` (an unmeasured family leaves ``auto`` to the force rule)."""
        return any(r.family == family for r in self.rows)

    def measured(self, rung: str, family: str) -> list[ImageRow]:
        """``rung``'s rows on ``family`` at depths from MIN_DEPTH (empty where it was not measured there)."""
        return [r for r in self.rows if r.rung == rung and r.family == family and r.depth >= MIN_DEPTH - 1e-12]

    def verdict(self, rung: str, family: str) -> tuple[float, str | None]:
        """(worst |force error| over the family's rows, why the image fails or None) for ``rung``; (inf, why) where
        the family was not measured for the rung."""
        rows = self.measured(rung, family)
        if not rows:
            return math.inf, f"its image is not measured on {family}s (the image table)"
        worst = max(abs(r.force_error) for r in rows)
        bad_rms = [r for r in rows if r.rms_share > RMS_LIMIT]
        bad_asym = [r for r in rows if not r.asymmetry_ok]
        if bad_asym:
            return worst, (f"its image over {family}s has the wrong asymmetry in {len(bad_asym)} of {len(rows)} "
                           "measured presses (the image table)")
        if bad_rms:
            share = max(r.rms_share for r in bad_rms)
            return worst, f"its image over {family}s is up to {share:.0%} of the peak off per sensel (the image table)"
        return worst, None


    def closest(self, rungs: tuple[str, ...], family: str, tolerance: float) -> tuple[str, float, float] | None:
        """Among ``rungs`` measured on ``family``: those whose worst force error is within ``tolerance`` (else those
        with the smallest), and of those the one whose image is closest to the reference (the smallest share of
        presses with the asymmetry wrong, then the smallest worst rms share); returned with both shares. None if
        none was measured."""
        scored = {}
        for rung in rungs:
            rows = self.measured(rung, family)
            if rows:
                scored[rung] = (max(abs(r.force_error) for r in rows),
                                sum(not r.asymmetry_ok for r in rows) / len(rows), max(r.rms_share for r in rows))
        if not scored:
            return None
        nearest = min(v[0] for v in scored.values())
        # none within: those whose force is nearest (rungs sharing one contact law tie), the image decides
        within = ([r for r, v in scored.items() if v[0] <= tolerance]
                  or [r for r, v in scored.items() if v[0] <= nearest * (1 + 1e-9)])
        best = min(within, key=lambda r: scored[r][1:])
        return best, scored[best][1], scored[best][2]


def rows_from_scores(scores: list[ImageScore]) -> list[ImageRow]:
    """One row per score and depth."""
    out = []
    for s in scores:
        e = s.errors
        ok = e.asymmetry_ok()
        for k, d in enumerate(e.depth):
            out.append(ImageRow(s.case, s.family, s.split, s.rung, float(d), float(e.force_error[k]),
                                float(e.rms_share[k]), bool(ok[k]), int(e.active[k]), int(e.reference_active[k])))
    return out


def format_summary(rows: list[ImageRow]) -> str:
    """The image columns as text: per rung, family and split, the worst |force error| and rms share over depths
    from MIN_DEPTH, and how many cases have the asymmetry right at every such depth."""
    lines = ["image against the 3-D FE (worst over depths >= 1 mm): rung, family, split, cases, |force error|, "
             "rms share of the peak, cases with the asymmetry right"]
    keys = sorted({(r.rung, r.family, r.split) for r in rows})
    for rung, family, split in keys:
        sel = [r for r in rows if (r.rung, r.family, r.split) == (rung, family, split) and r.depth >= MIN_DEPTH - 1e-12]
        if not sel:
            continue
        cases = sorted({r.case for r in sel})
        ok = sum(all(r.asymmetry_ok for r in sel if r.case == c) for c in cases)
        force = 100 * max(abs(r.force_error) for r in sel)
        lines.append(f"  {rung:<8} {family:<6} {split:<6} {len(cases):3d}  {force:5.1f}%  "
                     f"{100 * max(r.rms_share for r in sel):5.1f}%  {ok}/{len(cases)}")
    return "\n".join(lines)


def table_document(rows: list[ImageRow], measured_with: dict) -> dict:
    """The JSON document of the image table."""
    return {"format": FORMAT, "version": VERSION, "measured_with": measured_with,
            "rows": [r.to_dict() for r in rows]}


def load_image_table(path: Path | str = IMAGE_TABLE_PATH) -> ImageTable:
    """Read and check models/image_validity.json (or ``path``), once per file version
    (:func:`palpate.core.files.per_file_version`: every source and every choice shares it)."""
    return _image_tables(path)


def _read_image_table(path: Path) -> ImageTable:
    doc = read_document(path, "the image validity table", FORMAT, VERSION,
                        "run benchmarks/image_validity.py --write")
    raw = doc.get("rows")
    if not isinstance(raw, list) or len(raw) > 100_000:
        raise ValidationError(f"{path}: key 'rows' must be a list of at most 100000 rows")
    rows = []
    for i, r in enumerate(raw):
        try:
            row = ImageRow(case=str(r["case"]), family=str(r["family"]), split=str(r["split"]), rung=str(r["rung"]),
                           depth=float(r["depth"]), force_error=float(r["force_error"]),
                           rms_share=float(r["rms_share"]), asymmetry_ok=bool(r["asymmetry_ok"]),
                           active=int(r["active"]), reference_active=int(r["reference_active"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise ValidationError(f"{path}: row {i}: {exc}") from None
        if not (np.isfinite([row.depth, row.force_error, row.rms_share]).all() and row.depth > 0
                and row.rms_share >= 0):
            raise ValidationError(f"{path}: row {i}: depth, force_error and rms_share must be finite, depth > 0")
        rows.append(row)
    return ImageTable(tuple(rows))


_image_tables = per_file_version(_read_image_table)
