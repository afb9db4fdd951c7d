"""Where presses come from: the source/actuator interface and the registry that finds sources by name.

A source is anything that, asked to press at a target, returns the raw streams of that press: the MuJoCo
simulation, a recording being replayed, a Dynamixel finger with a Tekscan pad, or a human operator prompted
in the terminal. Sources register under the entry-point group ``palpate.sources`` so that the run loop in
core never imports MuJoCo or a serial library.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib.metadata import entry_points
from inspect import signature
from typing import Protocol, runtime_checkable

from palpate.core.errors import ValidationError
from palpate.core.extras import missing_extra, require_extra
from palpate.core.perception.streams import PressRecording
from palpate.core.world.scenario import Scenario
from palpate.core.world.scene import ObjectSpec, Scene, check_finite, finite_number

ENTRY_POINT_GROUP = "palpate.sources"


@dataclass(frozen=True)
class PressTarget:
    """Where and how to press.

    Attributes:
        x, y: target location on the object's surface, m (world frame).
        depth: indentation to reach beyond first contact, m (None if pressing to a force only).
        force: normal force to reach, N (None if pressing to a depth only). With both, the press stops at
            whichever comes first, as a person pressing a hard object stops before the planned depth.
        speed: approach/press speed, m/s.
        hold: time held at the deepest point, s.
        label: free text carried into the recording (e.g. "Region_3").
    """

    x: float
    y: float
    depth: float | None = 0.004
    force: float | None = None
    speed: float = 0.01
    hold: float = 0.0
    label: str = ""

    def __post_init__(self) -> None:
        optional = {name: value for name, value in (("depth", self.depth), ("force", self.force)) if value is not None}
        check_finite("PressTarget", x=self.x, y=self.y, speed=self.speed, hold=self.hold, **optional)
        if self.depth is None and self.force is None:
            raise ValidationError("PressTarget needs a depth (m), a force (N), or both (whichever comes first)")
        if self.depth is not None and not self.depth > 0:
            raise ValidationError(f"PressTarget.depth must be > 0 m, got {self.depth}")
        if self.force is not None and not self.force > 0:
            raise ValidationError(f"PressTarget.force must be > 0 N, got {self.force}")
        if not self.speed > 0:
            raise ValidationError(f"PressTarget.speed must be > 0 m/s, got {self.speed}")
        if self.hold < 0:
            raise ValidationError(f"PressTarget.hold must be >= 0 s, got {self.hold}")


def check_seed(value, where: str) -> int:
    """``value`` as a seed: a whole number >= 0 (a float that is one is taken as it; a press draws from
    ``numpy.random.SeedSequence([seed, n])``, which takes no other); ValidationError naming ``where`` otherwise."""
    if not (finite_number(value) and value >= 0 and value == int(value)):
        raise ValidationError(f"{where} must be a whole number >= 0, got {value!r}")
    return int(value)


@runtime_checkable
class PressSource(Protocol):
    """A source that can be asked for one press-and-release at a target."""

    def press(self, target: PressTarget) -> PressRecording:  # pragma: no cover - protocol
        """Perform (or replay) one press-and-release and return its raw streams."""
        ...


def press_all(source: PressSource, targets: list[PressTarget]) -> list[PressRecording]:
    """``[source.press(t) for t in targets]``: in one call when the source batches (a ``press_many(targets)``
    method, e.g. the simulated source's, whose results equal its loop's), press by press otherwise."""
    many = getattr(source, "press_many", None)
    if callable(many):
        return list(many(targets))
    return [source.press(t) for t in targets]


def available_sources() -> dict[str, str]:
    """Names of registered sources mapped to their import paths."""
    return {ep.name: ep.value for ep in entry_points(group=ENTRY_POINT_GROUP)}


def load_source(name: str):
    """Return the factory registered as ``name`` in ``palpate.sources``.

    Raises ValidationError naming the known sources if ``name`` is not registered, and MissingExtraError naming the
    extra to install if the source, or a module its ``requires`` attribute lists (imported only when it presses),
    is missing.
    """
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        if ep.name == name:
            try:
                factory = ep.load()
            except ImportError as exc:
                raise missing_extra(exc, f"the {name!r} source") from None
            require_extra(f"the {name!r} source", *getattr(factory, "requires", ()))
            return factory
    known = ", ".join(sorted(available_sources())) or "none (is palpate installed?)"
    raise ValidationError(f"unknown source {name!r}; registered sources: {known}")


def scenario_source_maker(scenario: Scenario, name: str = "sim"):
    """``make(objects, seed, variability)`` building the registered source ``name`` on the scenario's fingertip and
    sensors (and its ``[realism]`` profile, when not ideal): the shape every exploration and training loop asks for a
    source in. A source that takes ``laws`` gets one dict shared by every source the maker makes."""
    factory = load_source(name)
    # the scenario's tolerance for ``auto`` and flex's iteration limit, given to the sources that take them;
    # its realism profile when not ideal
    takes = signature(factory).parameters
    extra = {"tolerance": scenario.fidelity_tolerance} if "tolerance" in takes else {}
    if scenario.flex_iterations is not None and "flex_iterations" in takes:
        extra["flex_iterations"] = scenario.flex_iterations
    if scenario.realism.profile != "ideal":
        extra["realism"] = scenario.realism.profile
    if "laws" in takes:
        # one dict for every source this maker makes (training, each object, the ceiling): what a source solved
        # for a stack or a press point serves the others
        extra["laws"] = {}

    def make(objects: tuple[ObjectSpec, ...], seed: int, variability: str):
        scene = Scene(objects, scenario.fingertip, scenario.taxels, scenario.pose)
        return factory(scene, fidelity=scenario.fidelity, seed=seed, variability=variability, **extra)

    return make
