"""Who presses during exploration: ``sim`` (the registered simulated source) or a kind registered in the
entry-point group ``palpate.actuators`` (a person, a Dynamixel finger, ...).

The registry is the one source of truth for actuator kinds: the scenario schema and the command line take the
names from it. A registered kind is an :class:`ActuatorKind`: the keys of its ``[actuator]`` table, a parser that
validates them into its own frozen options, and the factory that makes the actuator. core never imports a kind's
module: it is found through its entry point, so the run loop does not depend on serial or servo libraries.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path

from palpate.core.errors import ValidationError
from palpate.core.extras import missing_extra
from palpate.core.world.table_reader import TableReader

ACTUATOR_GROUP = "palpate.actuators"
#: The simulated finger: no entry point, no options (it is the registered source of ``training.source``).
SIM = "sim"


@dataclass(frozen=True)
class ActuatorKind:
    """A registered exploration actuator.

    Attributes:
        keys: the keys of its ``[actuator]`` table besides ``kind``.
        parse: ``parse(reader, base_dir) -> options``: validates those keys (through ``reader``, so errors name
            the file and key) into the kind's own frozen options; relative paths resolve against ``base_dir``.
            The options may have ``perception``: a dict saying how the actuator's presses are perceived when not
            as taxels (e.g. ``palpate.core.perception.force_channel.PERCEPTION``); the run trains its memory alike.
        make: ``make(request, *, check_only=False) -> actuator | None``: with ``check_only`` it only checks the
            request (before any training); otherwise it returns something with ``press(PressTarget)``.
        extra: the optional dependency group (``pip install 'palpate[extra]'``) the kind needs, if any.
    """

    keys: tuple[str, ...]
    parse: Callable[[TableReader, Path], object]
    make: Callable[..., object]
    extra: str | None = None


def actuator_names() -> tuple[str, ...]:
    """``sim`` and every registered kind, in name order (read from the installed metadata, nothing imported)."""
    return (SIM, *sorted({ep.name for ep in entry_points(group=ACTUATOR_GROUP)} - {SIM}))


def load_actuator_kind(name: str) -> ActuatorKind:
    """The :class:`ActuatorKind` registered as ``name``; ValidationError naming the known kinds, or the optional
    dependency to install when the kind's module cannot be imported."""
    found = {ep.name: ep for ep in entry_points(group=ACTUATOR_GROUP)}
    if name not in found:
        raise ValidationError(f"actuator kind {name!r} is not registered in {ACTUATOR_GROUP}; known: "
                              f"{', '.join(actuator_names())}")
    try:
        kind = found[name].load()
    except ImportError as exc:
        raise missing_extra(exc, f"actuator kind {name!r}") from None
    if not isinstance(kind, ActuatorKind):
        raise ValidationError(f"entry point {name!r} in {ACTUATOR_GROUP} is {type(kind).__name__}, not an "
                              "ActuatorKind")
    return kind


def owner_of(key: str, but: str) -> str | None:
    """The registered kind (other than ``but``) whose ``[actuator]`` keys include ``key``, if any: an error can then
    say whose key it is."""
    for name in actuator_names():
        if name in (SIM, but):
            continue
        try:
            kind = load_actuator_kind(name)
        except ValidationError:
            continue
        if key in kind.keys:
            return name
    return None
