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
    gives them, integrated together per pad (same footprints, contact centre and order)."""
    out: list[np.ndarray | None] = [None] * len(samples)
    groups: dict[tuple, list[int]] = {}
    for i, s in enumerate(samples):
        key = (id(s.pad), s.order, float(s.centre[0]), float(s.centre[1]), s.law.tip_radius,
               s.law.coeffs.shape[1], s.bounds.shape)
        groups.setdefault(key, []).append(i)
    for members in groups.values():
        for i, p in zip(members, _group_pressure([samples[i] for i in members]), strict=True):
            out[i] = p
    return out


def _group_pressure(group: list[AnalyticSamples]) -> list[np.ndarray]:
    """Pressures of presses on one pad (see :func:`batch_sensel_pressure`)."""
    first = group[0]
    radius = first.law.tip_radius
    # one basis evaluation per law over the depths of all its presses (np.interp is elementwise)
    by_law: dict[int, list[int]] = {}
    for i, s in enumerate(group):
        by_law.setdefault(id(s.law), []).append(i)
    depths = [np.maximum(np.atleast_1d(np.asarray(s.depth, dtype=float)), 0.0) for s in group]
    radii: list[np.ndarray | None] = [None] * len(group)
    coeffs: list[np.ndarray | None] = [None] * len(group)
    for members in by_law.values():
        law = group[members[0]].law
        basis = law.basis_at(np.concatenate([depths[i] for i in members]))
        cut = np.cumsum([len(depths[i]) for i in members])[:-1]
        for i, r, c in zip(members, np.split(basis.radii, cut), np.split(basis.coeffs, cut), strict=True):
            radii[i], coeffs[i] = r, c
    # profile-major within each press, as one press lays them out; presses one after another
    sq = np.concatenate([(r**2 / radius).T.reshape(-1) for r in radii])
    ye = np.concatenate([(c * np.pi * radius / 2.0).T.reshape(-1) for c in coeffs])
    every = hertz_sensel_pressure(sq, ye, radius, first.bounds, first.centre, order=first.order, pad=first.pad)
    rows, cols = first.bounds.shape[:2]
    k_max = first.law.coeffs.shape[1]
    out, start = [], 0
    for d in depths:
        n = len(d)
        mine = every[start:start + k_max * n].reshape((k_max, n, rows, cols))
        start += k_max * n
        acc = np.zeros((n, rows, cols))
        for k in range(k_max):
            acc += mine[k]
        out.append(np.maximum(acc, 0.0))
    return out
