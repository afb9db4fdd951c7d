"""Boundary templates: the taxel image a press makes beside a straight wall between two materials, tabulated once by
an image-true rung for one pad and read by :mod:`.reading`.

A wall is the line n . r = d in the pad's plane (r from the press axis, n = (cos t, sin t)), the harder material on
the side n . r > d; its contrast is the harder over the softer modulus (> 1). Images are pressures, Pa, for a softer
modulus of :data:`REFERENCE_MODULUS` (a linear-elastic contact's pressure at a given depth scales with the modulus,
so the reading fits that scale). The file holds angles 0-45 deg only; the pad's square symmetry gives the rest.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.files import decimal_array, number_array, pack_decimals, read_json

FORMAT = "palpate-boundary-templates"
VERSION = 1
TEMPLATES_FILE = "boundary_templates.json"
#: The softer side's modulus the stored images are for, Pa.
REFERENCE_MODULUS = 1e5
#: Largest number of stored images a file may hold (depths x angles x offsets x contrasts).
MAX_IMAGES = 20000


@dataclass(frozen=True)
class Pad:
    """The pad the templates were made for: tip radius, pitch and sensel side, m; rows x cols sensels."""

    radius: float
    rows: int
    cols: int
    pitch: float
    sensel_size: float

    @classmethod
    def of(cls, tip) -> Pad:
        """The pad of a fingertip (a :class:`~palpate.core.world.scene.FingertipSpec`)."""
        return cls(tip.radius, tip.rows, tip.cols, tip.pitch, tip.sensel_size)

    @classmethod
    def from_dict(cls, doc: dict) -> Pad:
        """The pad of a templates file's ``pad`` object (KeyError, TypeError or ValueError when malformed)."""
        return cls(float(doc["radius"]), int(doc["rows"]), int(doc["cols"]), float(doc["pitch"]),
                   float(doc["sensel_size"]))

    def to_dict(self) -> dict:
        """The pad as a templates file holds it."""
        return {"radius": self.radius, "rows": self.rows, "cols": self.cols, "pitch": self.pitch,
                "sensel_size": self.sensel_size}

    def matches(self, other: Pad, rtol: float = 1e-6) -> bool:
        """True when ``other`` is the same pad (lengths within ``rtol``)."""
        same = (self.rows, self.cols) == (other.rows, other.cols)
        lengths = np.array([self.radius, self.pitch, self.sensel_size])
        theirs = np.array([other.radius, other.pitch, other.sensel_size])
        return same and bool(np.allclose(lengths, theirs, rtol=rtol, atol=0.0))


@dataclass(frozen=True)
class BoundaryTemplates:
    """Images beside walls, every angle of the full circle.

    Attributes:
        pad: the pad they were made for.
        poisson: both materials' Poisson ratio.
        depths: indentations, m, (D,) increasing.
        angles: wall normal angles t, rad, (A,) in [0, 2 pi).
        offsets: d, m, (O,) increasing (negative: the press axis on the harder side).
        contrasts: harder over softer modulus, (C,) increasing, > 1.
        wall: pressures, Pa, (D, A, O, C, rows, cols), softer modulus REFERENCE_MODULUS.
        plain: pressures on one material of modulus REFERENCE_MODULUS, Pa, (D, rows, cols).
    """

    pad: Pad
    poisson: float
    depths: np.ndarray
    angles: np.ndarray
    offsets: np.ndarray
    contrasts: np.ndarray
    wall: np.ndarray
    plain: np.ndarray

    def at_depth(self, depth: float) -> tuple[np.ndarray, np.ndarray]:
        """The wall (A, O, C, rows, cols) and plain (rows, cols) images at ``depth`` (m), linear between the stored
        depths and clamped to their range."""
        if len(self.depths) == 1:
            return self.wall[0], self.plain[0]
        k, w = bracket(self.depths, float(depth))
        return ((1 - w) * self.wall[k] + w * self.wall[k + 1], (1 - w) * self.plain[k] + w * self.plain[k + 1])


def bracket(grid: np.ndarray, x):
    """Where ``x`` (a number or an array) lies on an increasing ``grid``, clamped to its range: the index ``k`` of
    the node below and the weight ``w`` of node k + 1 in a linear interpolation, value = (1 - w) v[k] + w v[k + 1]
    (0 and 0 on a one-node grid)."""
    x = np.clip(np.asarray(x, dtype=float), grid[0], grid[-1])
    if len(grid) == 1:
        return np.zeros(x.shape, dtype=int), np.zeros(x.shape)
    k = np.clip(np.searchsorted(grid, x) - 1, 0, len(grid) - 2)
    return k, (x - grid[k]) / (grid[k + 1] - grid[k])


def read_template_document(path: str | Path, what: str, maker: str) -> object:
    """The JSON document of a templates file (``what``, e.g. "boundary templates"); a missing one is a
    ValidationError that says how to make it (``maker``: the script that writes it)."""
    path = Path(path)
    if not path.exists():
        raise ValidationError(f"{path}: {what} not found; make them with `python {maker} --write`")
    return read_json(path, what)


def _diagonal(image: np.ndarray) -> np.ndarray:
    """The image mirrored about the pad's x = y diagonal (t -> 90 deg - t); square pads only."""
    return np.swapaxes(image[..., ::-1, ::-1], -1, -2)


def full_circle(angles_deg: np.ndarray, wall: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Angles 0-45 deg (and their images, angle on axis 1) spread over the circle by the square pad's eight
    symmetries: mirrors about the diagonal (t -> 90 - t), the y axis (180 - t) and the x axis (-t), and their
    compositions. An angle reached from several stored ones (0 and 45 deg are their own mirrors) takes the mean of
    their images, so that the set turns with the pad exactly.

    Returns angles in rad, increasing in [0, 2 pi), and images with the angle on axis 1.
    """
    by_angle: dict[int, list[np.ndarray]] = {}
    for a, img in zip(angles_deg, np.moveaxis(wall, 1, 0), strict=True):
        for diag, x_mirror, y_mirror in itertools.product((False, True), repeat=3):
            deg, out = float(a), img
            if diag:
                deg, out = 90 - deg, _diagonal(out)
            if x_mirror:
                deg, out = 180 - deg, out[..., :, ::-1]
            if y_mirror:
                deg, out = -deg, out[..., ::-1, :]
            by_angle.setdefault(int(round(deg * 1000)) % 360000, []).append(out)
    keys = sorted(by_angle)
    return np.radians(np.array(keys) / 1000), np.stack([np.mean(by_angle[k], axis=0) for k in keys], axis=1)


def _increasing(arr: np.ndarray, where: str) -> None:
    if np.any(np.diff(arr) <= 0):
        raise ValidationError(f"{where} must be strictly increasing")


def templates_from_document(doc: object, source: str) -> BoundaryTemplates:
    """Validate a templates document (see :func:`read_templates`) and spread its angles over the circle."""
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or doc.get("version") != VERSION:
        raise ValidationError(f"{source}: not a {FORMAT} file of version {VERSION}")
    try:
        pad = Pad.from_dict(doc["pad"])
        poisson = float(doc["poisson"])
        depths = number_array(doc["depths"], f"{source}: depths", 1, 64)
        angles = number_array(doc["angles_deg"], f"{source}: angles_deg", 1, 64)
        offsets = number_array(doc["offsets"], f"{source}: offsets", 1, 256)
        contrasts = number_array(doc["contrasts"], f"{source}: contrasts", 1, 64)
        wall = decimal_array(doc["wall"], f"{source}: wall", 6, MAX_IMAGES * 64)
        plain = decimal_array(doc["plain"], f"{source}: plain", 3, 64 * 64)
    except (KeyError, TypeError, ValueError) as exc:
        raise ValidationError(f"{source}: a templates file needs pad, poisson, depths, angles_deg, offsets, "
                              f"contrasts, wall and plain ({exc})") from None
    if not (0 < pad.sensel_size <= pad.pitch < pad.radius < 0.1) or pad.rows != pad.cols or not 1 < pad.rows <= 64:
        raise ValidationError(f"{source}: pad must be square with 0 < sensel_size <= pitch < radius < 0.1 m")
    if not 0.0 <= poisson < 0.5:
        raise ValidationError(f"{source}: poisson must be in [0, 0.5), got {poisson}")
    for arr, name in ((depths, "depths"), (angles, "angles_deg"), (offsets, "offsets"), (contrasts, "contrasts")):
        _increasing(arr, f"{source}: {name}")
    if not (0 < depths[0] and depths[-1] < pad.radius and np.all(np.abs(offsets) < 0.05) and contrasts[0] > 1
            and contrasts[-1] < 1e4 and angles[0] >= 0 and angles[-1] <= 45):
        raise ValidationError(f"{source}: depths must be in (0, radius), |offsets| < 0.05 m, contrasts in (1, 1e4) "
                              "and angles_deg in [0, 45]")
    shape = (len(depths), len(angles), len(offsets), len(contrasts), pad.rows, pad.cols)
    if wall.shape != shape or plain.shape != (len(depths), pad.rows, pad.cols):
        raise ValidationError(f"{source}: wall must have shape {shape} and plain {(len(depths), pad.rows, pad.cols)}")
    if np.any(wall < 0) or np.any(plain < 0) or np.any(wall > 1e9) or np.any(plain > 1e9):
        raise ValidationError(f"{source}: pressures must be in [0, 1e9] Pa")
    rad, full = full_circle(angles, wall)
    return BoundaryTemplates(pad, poisson, depths, rad, offsets, contrasts, full, plain)


def read_templates(path: str | Path) -> BoundaryTemplates:
    """The templates in ``path``, validated (the shipped ones:
    :func:`palpate.core.session.boundaries.shipped_templates`).

    Raises:
        ValidationError: missing, not JSON, of another format, or any array of the wrong shape or out of range.
    """
    doc = read_template_document(path, "boundary templates", "benchmarks/boundary_templates.py")
    return templates_from_document(doc, str(path))


def templates_document(pad: Pad, poisson: float, depths, angles_deg, offsets, contrasts, wall, plain,
                       source: str) -> dict:
    """The JSON document :func:`read_templates` reads (angles 0-45 deg; see :class:`BoundaryTemplates`)."""
    return {"format": FORMAT, "version": VERSION, "source": source,
            "pad": pad.to_dict(),
            "poisson": poisson, "depths": list(map(float, depths)), "angles_deg": list(map(float, angles_deg)),
            "offsets": list(map(float, offsets)), "contrasts": list(map(float, contrasts)),
            "wall": pack_decimals(wall, 1), "plain": pack_decimals(plain, 1)}
