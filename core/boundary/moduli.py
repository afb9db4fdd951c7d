"""Which material each side of a read wall is: the log moduli a boundary reading gives for its softer and harder
side, compared with those the same reading gives on presses of the reference materials (their training presses).

Everything stays in the reading's own units (log of Pa times the image's units per Pa), so no gain is needed: the
references and the explored object are read by the same pad.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.boundary.reading import BoundaryReading
from palpate.core.errors import ValidationError

#: Smallest spread of a material's log modulus: the reading's own scatter between presses and objects.
MIN_LOG_SD = 0.15


@dataclass(frozen=True)
class MaterialModuli:
    """Per reference material, the mean and spread of the log modulus its presses read as.

    Attributes:
        materials: names, in the order of ``log_mean``.
        log_mean, log_sd: (M,) each.
    """

    materials: tuple[str, ...]
    log_mean: np.ndarray
    log_sd: np.ndarray

    def probabilities(self, log_modulus: float, order: tuple[str, ...] | None = None) -> np.ndarray:
        """Distribution over materials (in ``order``, default ``materials``) of a side read as ``log_modulus``:
        Gaussian in the log modulus, flat prior."""
        order = self.materials if order is None else order
        idx = [self.materials.index(m) if m in self.materials else -1 for m in order]
        z = (log_modulus - self.log_mean) / self.log_sd
        ll = -0.5 * z**2 - np.log(self.log_sd)
        p = np.exp(ll - ll.max())
        out = np.array([p[i] if i >= 0 else 0.0 for i in idx])
        total = out.sum()
        return out / total if total > 0 else np.full(len(order), 1.0 / len(order))


def material_moduli(readings: dict[str, list[BoundaryReading]]) -> MaterialModuli:
    """The moduli of reference materials from readings of presses on each (one material under each press).

    Raises:
        ValidationError: a material without a reading.
    """
    names, mean, sd = [], [], []
    for name, rs in readings.items():
        logs = np.array([r.log_plain for r in rs if r is not None and np.isfinite(r.log_plain)])
        if len(logs) == 0:
            raise ValidationError(f"material_moduli: no reading of {name!r}")
        names.append(name)
        mean.append(float(np.mean(logs)))
        sd.append(max(float(np.std(logs)), MIN_LOG_SD))
    return MaterialModuli(tuple(names), np.array(mean), np.array(sd))
