"""The analytic rung for many presses at once: every press's sensel pressures in one integration.

Each press is sampled as one press is (:func:`palpate.sim.analytic.analytic_samples`: its refusals, its law, its
pad); then the Hertz profiles of every sample of every press that shares a pad go through one
:func:`palpate.sim.analytic.hertz_sensel_pressure` call, and each press's profiles are summed in the order one
press sums them. Every operation is elementwise or a reduction over one sample's own values, so a press's pressures
do not depend on what else is in the batch: they equal :func:`palpate.sim.analytic.run_analytic_press`'s.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from palpate.core.world.scene import ObjectSpec, Scene
from palpate.sim.analytic import AnalyticSamples, analytic_samples, analytic_trace, hertz_sensel_pressure
from palpate.sim.controller import PressProfile
from palpate.sim.trace import PhysicsTrace


@dataclass(frozen=True)
class AnalyticJob:
    """One analytic press of a batch: the scene (fingertip, taxel rate), the pressed object, the trajectory the
    physics follows, its contact law (None: solved here) and the ``pads`` cache of its source (or None)."""

    scene: Scene
    obj: ObjectSpec
    profile: PressProfile
    law: object = None
    pads: dict | None = None


def cpu_analytic_traces(jobs: Sequence[AnalyticJob]) -> list[PhysicsTrace]:
    """The physics traces of analytic presses, vectorised across them on the CPU (numpy); the ``cpu`` backend."""
    samples = [analytic_samples(j.scene, j.obj, j.profile, law=j.law, pads=j.pads) for j in jobs]
    pressures = batch_sensel_pressure(samples)
    return [analytic_trace(s, p) for s, p in zip(samples, pressures, strict=True)]


def batch_sensel_pressure(samples: Sequence[AnalyticSamples]) -> list[np.ndarray]:
    """Each press's sensel pressures (n_i, rows, cols), Pa, as :func:`palpate.sim.analytic.law_sensel_pressure`
    gives them, integrated together per pad (same footprints and contact centre)."""
    out: list[np.ndarray | None] = [None] * len(samples)
    groups: dict[tuple, list[int]] = {}
    for i, s in enumerate(samples):
        key = (id(s.pad), float(s.centre[0]), float(s.centre[1]), s.law.tip_radius,
               s.law.coeffs.shape[1], s.bounds.shape)
        groups.setdefault(key, []).append(i)
    for members in groups.values():
        for i, p in zip(members, _group_pressure([samples[i] for i in members]), strict=True):
            out[i] = p
    return out


#: Hertz profiles integrated per call: the arrays of one call stay in the CPU's cache (a call over every profile of
#: a large batch at once is slower per profile than a press alone).
CHUNK = 1024


def _group_pressure(group: list[AnalyticSamples]) -> list[np.ndarray]:
    """Pressures of presses on one pad (see :func:`batch_sensel_pressure`): each law's distinct depths integrated
    once (presses of one robot protocol repeat them), their profiles in chunks, summed profile by profile."""
    first = group[0]
    radius, bounds, centre, pad = first.law.tip_radius, first.bounds, first.centre, first.pad
    rows, cols = bounds.shape[:2]
    by_law: dict[int, list[int]] = {}
    for i, s in enumerate(group):
        by_law.setdefault(id(s.law), []).append(i)
    depths = [np.maximum(np.atleast_1d(np.asarray(s.depth, dtype=float)), 0.0) for s in group]
    out: list[np.ndarray | None] = [None] * len(group)
    for members in by_law.values():
        law = group[members[0]].law
        every_depth = np.concatenate([depths[i] for i in members])
        uniq, inverse = np.unique(every_depth, return_inverse=True)
        basis = law.basis_at(uniq)  # np.interp: elementwise, so a depth's basis is the one a press alone gets
        # profile-major, as law_sensel_pressure lays them out
        sq = (basis.radii**2 / radius).T
        ye = (basis.coeffs * np.pi * radius / 2.0).T
        k_max, n = sq.shape
        every = np.empty((k_max, n, rows, cols))
        for start in range(0, n, max(CHUNK // k_max, 1)):
            stop = min(start + max(CHUNK // k_max, 1), n)
            part = hertz_sensel_pressure(sq[:, start:stop].reshape(-1), ye[:, start:stop].reshape(-1), radius,
                                         bounds, centre, pad=pad)
            every[:, start:stop] = part.reshape(k_max, stop - start, rows, cols)
        acc = np.zeros((n, rows, cols))
        for k in range(k_max):
            acc += every[k]
        pressure = np.maximum(acc, 0.0)
        cut = np.cumsum([len(depths[i]) for i in members])[:-1]
        for i, idx in zip(members, np.split(inverse.reshape(-1), cut), strict=True):
            out[i] = pressure[idx]
    return out
