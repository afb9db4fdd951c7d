"""Which actuator presses during exploration: the simulated finger, a person, or a Dynamixel finger.

The exploration loop (:func:`palpate.core.session.explore.explore_object`) presses through whatever ``make(objects,
seed, variability)`` returns. :func:`open_actuators` gives the run that function for the scenario's ``[actuator]``:

- ``sim``: the registered simulated source (``training.source``, default ``sim``), the one that trains the memory;
- any other kind: an :class:`~palpate.core.world.actuator_kinds.ActuatorKind` registered under the entry-point
  group ``palpate.actuators`` (so core never imports hardware or sim), whose factory is called once per explored
  object with one signature::

      make(request: ActuatorRequest, *, check_only: bool = False) -> PressSource | None

  With ``check_only`` the factory validates all it can without touching a device (files, ports named, the reach
  of every cell the policy may press) and returns None: the run does this for every object before training, so a
  scenario the actuator cannot do fails at once, before any servo moves. The source it returns has
  ``press(PressTarget) -> PressRecording`` and may have ``close()``, which the run calls when the object is
  explored (or the run fails). ``operator`` is :mod:`palpate.core.session.operator_actuator`; ``dynamixel`` is
  :mod:`palpate.hardware.dynamixel.actuator_source`.

Training with a non-sim actuator: the haptic memory comes from ``training.memory`` (a memory.json) when given,
else it is trained in simulation by ``training.source``; if that source cannot be loaded the run stops at once
with an error that says to give ``training.memory``.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.mapping.geometry import MapGeometry
from palpate.core.world.actuator_kinds import load_actuator_kind
from palpate.core.world.scenario import ActuatorSpec, Scenario
from palpate.core.world.scene import ObjectSpec, Scene


@dataclass(frozen=True)
class ActuatorRequest:
    """Everything an actuator factory gets for one explored object (lengths m, forces N, speeds m/s).

    Attributes:
        spec: the scenario's ``[actuator]`` (kind and kind-specific options).
        scene: the object explored (``scene.objects[0]``) with the scenario's fingertip and sensor models.
        origin: (x0, y0) corner of the object's map grid, m.
        cell_size: grid cell side, m.
        shape: (nx, ny) cells.
        cells: 0-based (ix, iy) of every cell the policy may press (the regions for ``predefined``, else all).
        targets: (n, 2) press points of ``cells`` (cell centres), m.
        depth: deepest press the exploration plans, m.
        max_force: force limit of a press, N (None: none).
        speed: press speed, m/s.
        seed: the object's seed (sensor noise of emulated devices).
        variability: "human" or "robot" (what the scenario asks; a robot actuator ignores it).
        materials: reference material names (the map's classes).
        n_objects: how many objects the scenario explores.
        out_dir: the run's output folder (figures), or None.
        input, output: text streams a person answers on and is prompted on.
    """

    spec: ActuatorSpec
    scene: Scene
    origin: tuple[float, float]
    cell_size: float
    shape: tuple[int, int]
    cells: tuple[tuple[int, int], ...]
    targets: np.ndarray
    depth: float
    max_force: float | None
    speed: float
    seed: int
    variability: str
    materials: tuple[str, ...]
    n_objects: int = 1
    out_dir: Path | None = None
    input: TextIO | None = None
    output: TextIO | None = None

    @property
    def obj(self) -> ObjectSpec:
        """The object explored."""
        return self.scene.objects[0]


def load_actuator(kind: str):
    """The factory ``make(request, *, check_only=False)`` of the actuator kind registered as ``kind``."""
    return load_actuator_kind(kind).make


def actuator_requests(scenario: Scenario, geometries: Mapping[str, MapGeometry], out_dir: Path | None = None,
                      input: TextIO | None = None, output: TextIO | None = None) -> dict[str, ActuatorRequest]:
    """One request per object of the scenario, keyed by object name (``geometries`` by object name, as
    :func:`~palpate.core.world.workspace.map_geometries` gives them)."""
    ex = scenario.exploration
    out = {}
    for entry in scenario.objects:
        geom = geometries[entry.spec.name]
        nx, ny = geom.plane_shape
        if ex.policy == "predefined":
            cells = tuple(dict.fromkeys((c - 1, r - 1) for c, r in entry.regions))
        else:
            cells = tuple((ix, iy) for iy in range(ny) for ix in range(nx))
        origin = geom.origin
        cell = geom.cell_size
        targets = np.array([[origin[0] + (ix + 0.5) * cell, origin[1] + (iy + 0.5) * cell] for ix, iy in cells],
                           dtype=float).reshape(-1, 2)
        out[entry.spec.name] = ActuatorRequest(
            spec=scenario.actuator, scene=Scene((entry.spec,), scenario.fingertip, scenario.taxels, scenario.pose),
            origin=origin, cell_size=cell, shape=(nx, ny), cells=cells, targets=targets, depth=ex.depth,
            max_force=ex.max_force, speed=ex.speed, seed=0, variability=ex.variability,
            materials=tuple(scenario.references), n_objects=len(scenario.objects), out_dir=out_dir,
            input=input, output=output)
    return out


@contextlib.contextmanager
def open_actuators(scenario: Scenario, out_dir: Path | None, geometries: Mapping[str, MapGeometry],
                   sim_source: Callable[[], Callable]):
    """The run's source makers: yields ``(make_training, make_exploring)``, each ``(objects, seed, variability)
    -> source``; ``make_training`` is None when the memory comes from ``training.memory`` and the actuator is not
    simulated.

    ``sim_source()`` returns the registered simulated source's maker (it may raise if that source cannot load).
    Every object's actuator request is checked before this yields (nothing moves before that); an actuator with
    ``close()`` is closed when the next object's is made and when the block ends. Prompts go to stderr (stdout
    carries the run's report) and answers come from stdin.
    """
    kind = scenario.actuator.kind
    needs_training = scenario.training.memory is None
    make_sim = None
    if kind == "sim" or needs_training:
        try:
            make_sim = sim_source()
        except (ValidationError, ImportError) as exc:
            if kind == "sim":
                raise
            raise ValidationError(f"actuator {kind!r} explores, and the haptic memory is trained in simulation "
                                  f"(training.source = {scenario.training.source!r}), which is unavailable: {exc}. "
                                  "Give training.memory = a memory.json (from palpate run or palpate memory "
                                  "train) instead") from None
    if kind == "sim":
        yield make_sim, make_sim
        return
    factory = load_actuator(kind)
    requests = actuator_requests(scenario, geometries, out_dir, sys.stdin, sys.stderr)
    where = str(scenario.path) if scenario.path else "scenario"
    for request in requests.values():
        try:
            factory(request, check_only=True)
        except ValidationError as exc:
            raise ValidationError(f"{where}: {exc}") from None
    current: list = []

    def close_current() -> None:
        while current:
            close = getattr(current.pop(), "close", None)
            if callable(close):
                close()

    def make(objects: tuple[ObjectSpec, ...], seed: int, variability: str):
        close_current()
        request = requests.get(objects[0].name) if len(objects) == 1 else None
        if request is None:
            raise ValidationError(f"actuator {kind!r} presses the scenario's objects one at a time; asked for "
                                  f"{[o.name for o in objects]}")
        from dataclasses import replace

        source = factory(replace(request, seed=int(seed), variability=variability))
        current.append(source)
        return source

    try:
        yield make_sim, make
    finally:
        close_current()
