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

from dataclasses import dataclass

import numpy as np

from palpate.core.errors import FitError, ValidationError

MIN_SAMPLES = 5


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
    from palpate.core.perception.fit import fit_press
    from palpate.core.perception.segment import Press

    c_D = np.asarray(c_D, dtype=float)
    if len(c_D) == 0:
        return []
    depth = float(c_D.max())
    reached = min(n_layers, int(np.ceil(depth / cell - 1e-9)))
    out: list[np.ndarray | None] = []
    for iz in range(reached):
        keep = c_D <= (iz + 1) * cell + 1e-12
        n = int(keep.sum())
        if n < MIN_SAMPLES:
            out.append(None)
            continue
        part = Press(index=0, t_onset=float(t[0]), t_peak=float(t[keep][-1]), t_release=float(t[-1]), h0=0.0,
                     location=(0.0, 0.0), depth=float(c_D[keep].max()), t=np.asarray(t)[keep],
                     c_P=np.asarray(c_P)[keep], c_A=np.asarray(c_A)[keep], c_D=c_D[keep], xy=np.zeros((n, 2)))
        try:
            out.append(np.asarray(fit_press(part).params, dtype=float))
        except FitError:
            out.append(None)
    return out


@dataclass
class LayeredMemory:
    """A haptic memory for whole presses plus one per voxel layer (presses cut at that layer's depth).

    Everything a HapticMemory offers (materials, predict_proba, save, ...) is the whole-press memory's; only
    :meth:`layer_posteriors` uses the per-layer memories.
    """

    full: object
    layers: list  # per layer: a HapticMemory, a material name (only it reaches the layer) or None
    cell: float

    def __getattr__(self, name):
        # Only called for attributes not found on the dataclass: delegate to the whole-press memory.
        if name in ("full", "layers", "cell"):
            raise AttributeError(name)
        return getattr(self.full, name)

    def layer_posteriors(self, t, c_P, c_A, c_D) -> list[np.ndarray | None]:
        """Posterior over the reference materials for each layer the press reached (None where unfittable)."""
        fits = layer_fits(t, c_P, c_A, c_D, self.cell, len(self.layers))
        materials = list(self.full.materials)
        out = []
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


def train_layered_memory(full, training: dict, cell: float, n_layers: int) -> LayeredMemory:
    """Train one memory per voxel layer from the training presses (dict material -> list of PressResult).

    A layer gets a memory over the materials with at least 3 presses fittable at that depth (the name of the
    material when only one reaches it, None when none does).
    """
    from palpate.core.perception.memory import HapticMemory

    if not cell > 0 or n_layers < 1:
        raise ValidationError(f"layered memory needs cell > 0 m and >= 1 layer, got {cell}, {n_layers}")
    per_layer: list[tuple[list, list]] = [([], []) for _ in range(n_layers)]
    for name, results in training.items():
        for res in results:
            if res.params is None:
                continue
            for iz, params in enumerate(layer_fits(res.t, res.c_P, res.c_A, res.c_D, cell, n_layers)):
                if params is not None:
                    per_layer[iz][0].append(params)
                    per_layer[iz][1].append(name)
    layers = []
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
    return LayeredMemory(full, layers, cell)
