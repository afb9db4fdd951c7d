"""Evidence per voxel layer from one press (seed 001, section 3.1): what the press says about each depth.

A press that reaches depth d passes through the voxel layers 0..k of its column. Seed 001 updates every voxel
containing a sample of the press, and observes that deeper voxels discriminate better. palpate gives layer iz
the posterior of the 3/2-power fit to the press samples from first contact down to the bottom of that layer, so
deeper layers see more of the press.

A fit to the first millimetres of a press is not distributed like a fit to a whole press (the contact area, for
one, has not spread yet), so layer iz is judged by a haptic memory trained on the training presses cut at the same
depth: :class:`LayeredMemory` holds one memory per layer. A layer's memory knows only the materials whose
training presses reached it: under the same force limit a hard material cannot be pressed that deep, so reaching
the layer is itself evidence against it (those materials get probability 0 there, which the map clamps to p_min).
A layer no training press reached gives no evidence.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from palpate.core import files, limits
from palpate.core.errors import FitError, ValidationError
from palpate.core.perception.fit import fit_samples
from palpate.core.perception.memory import HapticMemory
from palpate.core.perception.press import PressResult

MIN_SAMPLES = 5
FORMAT_NAME = "palpate.layered_memory"
FORMAT_VERSION = 1

#: What judges one layer: a memory over the materials that reach it, the one material that alone reaches it, or
#: None where no training press reached it.
LayerJudge = HapticMemory | str | None


def layer_fits(t: np.ndarray, c_P: np.ndarray, c_A: np.ndarray, c_D: np.ndarray, cell: float,
               n_layers: int) -> list[np.ndarray | None]:
    """Interaction parameters [n1, n2, a1, a2] of the press cut at the bottom of each layer.

    Args:
        t, c_P, c_A, c_D: press-phase samples (s, counts, m^2, m).
        cell: voxel side, m.
        n_layers: number of layers of the column.

    Returns:
        one entry per layer the press reached: the parameters, or None where the cut press could not be fitted
        (fewer than MIN_SAMPLES samples, constant contact area).
    """
    c_D = np.asarray(c_D, dtype=float)
    if len(c_D) == 0:
        return []
    c_P, c_A = np.asarray(c_P, dtype=float), np.asarray(c_A, dtype=float)
    depth = float(c_D.max())
    reached = min(n_layers, int(np.ceil(depth / cell - 1e-9)))
    out: list[np.ndarray | None] = []
    for iz in range(reached):
        keep = c_D <= (iz + 1) * cell + 1e-12
        if int(keep.sum()) < MIN_SAMPLES:
            out.append(None)
            continue
        try:
            out.append(fit_samples(c_P[keep], c_A[keep], c_D[keep], where=f"layer {iz}").params)
        except FitError:
            out.append(None)
    return out


@dataclass(frozen=True)
class LayeredMemory:
    """The whole-press haptic memory plus one judge per voxel layer (presses cut at that layer's depth).

    Attributes:
        full: the whole-press memory (its materials are the map's).
        layers: per layer, a :data:`LayerJudge`.
        cell: voxel side, m.
    """

    full: HapticMemory
    layers: tuple[LayerJudge, ...]
    cell: float

    @classmethod
    def whole_press(cls, full: HapticMemory, cell: float, n_layers: int) -> LayeredMemory:
        """Every layer judged by the whole-press memory (when no per-layer training is available)."""
        return cls(full, (full,) * n_layers, cell)

    @property
    def materials(self) -> list[str]:
        """The reference materials, in the whole-press memory's order."""
        return list(self.full.materials)

    def layer_posteriors(self, t, c_P, c_A, c_D) -> list[np.ndarray | None]:
        """Posterior over the reference materials for each layer the press reached (None where unfittable)."""
        fits = layer_fits(t, c_P, c_A, c_D, self.cell, len(self.layers))
        materials = self.materials
        out: list[np.ndarray | None] = []
        for iz, params in enumerate(fits):
            layer = self.layers[iz]
            if params is None or layer is None:
                out.append(None)
                continue
            post = np.zeros(len(materials))
            if isinstance(layer, str):  # one material alone reaches this depth
                post[materials.index(layer)] = 1.0
            else:
                post[[materials.index(m) for m in layer.materials]] = layer.predict_proba(params[None, :])[0]
            out.append(post)
        return out

    def save(self, path: str | Path) -> None:
        """Write the per-layer judges (JSON; the whole-press memory is saved on its own as memory.json)."""
        doc = {"format": FORMAT_NAME, "version": FORMAT_VERSION, "cell_size_m": self.cell,
               "layers": [m if m is None or isinstance(m, str) else m.to_dict() for m in self.layers]}
        files.write_text(path, json.dumps(doc))

    @classmethod
    def load(cls, full: HapticMemory, path: str | Path) -> LayeredMemory:
        """Read :meth:`save`'s file back around the whole-press memory ``full``."""
        doc = files.read_json(path, "layered memory")
        if not isinstance(doc, Mapping) or doc.get("format") != FORMAT_NAME or doc.get("version") != FORMAT_VERSION:
            raise ValidationError(f"{path}: key 'format' must be {FORMAT_NAME!r} version {FORMAT_VERSION}")
        raw_layers, cell = doc.get("layers"), doc.get("cell_size_m")
        if not isinstance(raw_layers, list) or not raw_layers:
            raise ValidationError(f"{path}: key 'layers' must be a non-empty list (a memory, a material name or "
                                  "null per layer)")
        limits.check("map_cells", f"{path}: key 'layers': layer count", len(raw_layers))
        if isinstance(cell, bool) or not isinstance(cell, (int, float)) or not (math.isfinite(cell) and cell > 0):
            raise ValidationError(f"{path}: key 'cell_size_m' must be a finite number > 0, got {files.brief(cell)}")
        layers = []
        for i, d in enumerate(raw_layers):
            if d is not None and not isinstance(d, (str, Mapping)):
                raise ValidationError(f"{path}: key 'layers[{i}]' must be a memory, a material name or null, got "
                                      f"{files.brief(d)}")
            if isinstance(d, str) and d not in full.materials:
                raise ValidationError(f"{path}: key 'layers[{i}]' names {files.brief(d)}, not a material of the "
                                      f"memory {list(full.materials)}")
            if isinstance(d, Mapping):
                d = HapticMemory.from_dict(d, source=f"{path}: layers[{i}]")
                if not set(d.materials) <= set(full.materials):
                    raise ValidationError(f"{path}: key 'layers[{i}]' judges materials {list(d.materials)}, not all "
                                          f"in the memory's {list(full.materials)}")
            layers.append(d)
        return cls(full, tuple(layers), float(cell))


def train_layered_memory(full: HapticMemory, training: Mapping[str, Sequence[PressResult]], cell: float,
                         n_layers: int) -> LayeredMemory:
    """Train one judge per voxel layer from the training presses (material name -> its perceived presses).

    A layer gets a memory over the materials with at least 3 presses fittable at that depth (the name of the
    material when only one reaches it, None when none does).
    """
    if not cell > 0 or n_layers < 1:
        raise ValidationError(f"layered memory needs cell > 0 m and >= 1 layer, got {cell}, {n_layers}")
    per_layer: list[tuple[list, list]] = [([], []) for _ in range(n_layers)]
    for name, results in training.items():
        for res in results:
            if res.fit is None:
                continue
            pr = res.press
            for iz, params in enumerate(layer_fits(pr.t, pr.c_P, pr.c_A, pr.c_D, cell, n_layers)):
                if params is not None:
                    per_layer[iz][0].append(params)
                    per_layer[iz][1].append(name)
    layers: list[LayerJudge] = []
    materials = list(full.materials)
    for params, labels in per_layer:
        reached = [m for m in materials if labels.count(m) >= 3]
        if not reached:
            layers.append(None)
        elif len(reached) == 1:
            layers.append(reached[0])
        else:
            keep = [i for i, name in enumerate(labels) if name in reached]
            layers.append(HapticMemory(materials=reached).fit(np.vstack([params[i] for i in keep]),
                                                              [labels[i] for i in keep]))
    return LayeredMemory(full, tuple(layers), cell)
