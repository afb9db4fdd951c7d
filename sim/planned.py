"""A simulated press as planned by its source, before its physics (:meth:`palpate.sim.source.SimSource.press` runs
plan, physics and record in turn; :mod:`palpate.sim.batch` plans many and runs their physics together)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import ObjectSpec
from palpate.sim.controller import PressProfile
from palpate.sim.validity.choice import Choice


@dataclass(frozen=True)
class PlannedPress:
    """A press planned by a source, before its physics: what it presses, its trajectory (``profile`` as commanded,
    ``physics_profile`` what the physics follows), its contact law when its rung uses one, its realism (or None),
    its physics step (s) and profile seed, the seeds of its taxel and pose noise, and its index in the source."""

    target: PressTarget
    obj: ObjectSpec
    choice: Choice
    mesh: object
    profile: PressProfile
    physics_profile: PressProfile
    law: object
    real: object
    timestep: float
    seed: int
    s_taxel: np.random.SeedSequence
    s_pose: np.random.SeedSequence
    index: int
