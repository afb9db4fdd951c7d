"""Leave-one-out cross-validation of the haptic memory (seed 000, section 6.8.2, Table 6.7)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.perception.memory import MIN_SAMPLES, HapticMemory
from palpate.core.perception.params import as_labels, as_params


@dataclass
class CrossValidation:
    """Result of :func:`leave_one_out`. Rows are the true material, columns the perceived one.

    Attributes:
        materials: names, in row/column order.
        counts: (M, M) number of presses of material i classified (MAP) as j.
        confusion: (M, M) counts divided by each row's total (Table 6.7 layout).
        mean_posterior: (M, M) mean posterior P(M = j | press) over the presses of material i.
        posteriors: (n, M) posterior of each held-out press, in input order.
        truth: (n,) index of each press's true material.
    """

    materials: list[str]
    counts: np.ndarray
    confusion: np.ndarray
    mean_posterior: np.ndarray
    posteriors: np.ndarray
    truth: np.ndarray

    @property
    def predicted(self) -> np.ndarray:
        """(n,) MAP material index of each held-out press."""
        return np.argmax(self.posteriors, axis=1)

    @property
    def accuracy(self) -> float:
        """Fraction of all presses classified correctly."""
        return float(np.trace(self.counts) / self.counts.sum())

    @property
    def per_material_accuracy(self) -> np.ndarray:
        """(M,) fraction of each material's presses classified correctly (the confusion diagonal)."""
        return np.diag(self.confusion).copy()

    def to_dict(self) -> dict:
        """JSON-ready summary: materials, confusion, mean_posterior, counts, accuracy."""
        return {
            "materials": list(self.materials),
            "confusion": self.confusion.tolist(),
            "mean_posterior": self.mean_posterior.tolist(),
            "counts": self.counts.astype(int).tolist(),
            "accuracy": self.accuracy,
            "per_material_accuracy": self.per_material_accuracy.tolist(),
        }


def leave_one_out(params, labels: Sequence[str], groups=None, **memory_kwargs) -> CrossValidation:
    """Leave-one-out cross-validation of the haptic memory (seed 000, sec. 6.8.2, Table 6.7).

    Each press is held out in turn; a memory is trained on all the others (for its own material that is the
    other n-1 presses, as in the thesis) and the held-out press is classified by MAP.

    Args:
        params: (n, 4) [n1, n2, a1, a2].
        labels: n material names.
        groups: None, or n integers: the presses of its material sharing the held-out press's group are held
            out with it (copies of one press in a bootstrap resample, so no copy trains the memory that reads its
            twin).
        **memory_kwargs: passed to :class:`HapticMemory` (materials, prior, min_eig, ddof, features).

    Needs at least MIN_SAMPLES + 1 presses per material, and MIN_SAMPLES left when a group is held out.
    """
    x = as_params(params)
    labs = as_labels(labels, x.shape[0])
    group = np.arange(len(x)) if groups is None else np.asarray(groups).reshape(-1)
    if group.shape != (len(x),) or group.dtype.kind not in "iu":
        raise ValidationError(f"groups must be {len(x)} integers, one per press, got {np.asarray(groups)!r}")
    full = HapticMemory(**memory_kwargs).fit(x, labs)
    materials = full.materials
    truth = full.index_of(labs)
    counts_per = np.bincount(truth, minlength=len(materials))
    for name, c in zip(materials, counts_per, strict=True):
        if c < MIN_SAMPLES + 1:
            raise ValidationError(
                f"material {name!r} has {c} presses; leave-one-out needs at least {MIN_SAMPLES + 1}"
            )
    kwargs = dict(memory_kwargs)
    kwargs["materials"] = materials
    post = np.empty((len(x), len(materials)))
    for i in range(len(x)):
        keep = (group != group[i]) | (truth != truth[i])
        left = int(np.sum(keep & (truth == truth[i])))
        if left < MIN_SAMPLES:
            raise ValidationError(f"press {i} of {materials[truth[i]]!r}: holding out its group leaves {left} "
                                  f"presses of it; the memory needs {MIN_SAMPLES}")
        mem = HapticMemory(**kwargs).fit(x[keep], [lab for lab, k in zip(labs, keep, strict=True) if k])
        post[i] = mem.predict_proba(x[i], features=mem.features)[0]
    return crossval_result(materials, truth, post)


def crossval_result(materials: Sequence[str], truth: np.ndarray, post: np.ndarray) -> CrossValidation:
    """The confusion and mean posterior of held-out posteriors ``post`` (n, M) of presses of material index
    ``truth`` (n,); every material needs at least one press."""
    m = len(materials)
    counts_per = np.bincount(truth, minlength=m)
    if np.any(counts_per == 0):
        missing = [name for name, c in zip(materials, counts_per, strict=True) if c == 0]
        raise ValidationError(f"cross-validation: no press of material(s) {missing}")
    counts = np.zeros((m, m))
    np.add.at(counts, (truth, np.argmax(post, axis=1)), 1)
    mean_post = np.zeros((m, m))
    np.add.at(mean_post, truth, post)
    mean_post /= counts_per[:, None]
    return CrossValidation(
        materials=list(materials),
        counts=counts,
        confusion=counts / counts_per[:, None],
        mean_posterior=mean_post,
        posteriors=post,
        truth=truth,
    )
