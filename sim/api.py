"""One-call script API: ``simulate_press(young, ...)`` for notebooks and other tools."""

from __future__ import annotations

from numbers import Real

from palpate.core.errors import ValidationError
from palpate.core.perception.streams import PressRecording
from palpate.core.session.sources import PressTarget, check_seed
from palpate.core.world.scene import FingertipSpec, Material, ObjectSpec, PoseSensorSpec, Scene, TaxelSensorSpec
from palpate.sim.source import SimSource

_OPTIONS = ("size", "thickness", "damping", "hold", "force", "variability", "timestep", "fingertip", "taxels",
            "pose", "material_name", "max_steps", "tolerance", "flex_iterations")


def simulate_press(
    young: float, poisson: float = 0.3, fidelity: str = "rigid", depth: float | None = 0.004, speed: float = 0.01,
    seed: int = 0, **scene_options,
) -> PressRecording:
    """Simulate one press-and-release on a block of one material (SI units).

    Each call builds its own source, so its contact law is solved again: for many presses of one block, keep a
    :class:`~palpate.sim.source.SimSource` and call its ``press`` (the law, the pad and the rigid model are kept).

    Args:
        young: Young's modulus, Pa.  poisson: Poisson ratio.
        fidelity: "analytic", "bem", "rigid", "flex" or "auto".
        depth: indentation to reach, m (None when pressing to ``force``).
        speed: press speed, m/s.
        seed: seed of press variability and sensor noise.
        **scene_options: size (block side, m, 0.1), thickness (m, 0.03), damping (s, 0), hold (s, 0),
            force (N, instead of depth), variability ("robot" or "human"), timestep (s), fingertip
            (FingertipSpec), taxels (TaxelSensorSpec), pose (PoseSensorSpec), material_name, max_steps (the
            step budget of one press, 200 000: a longer press is refused before it runs), tolerance (``auto``'s
            largest predicted force error, fraction, 0.05), flex_iterations (MuJoCo's iteration limit of a flex
            press, its default 100).

    Returns:
        a PressRecording with ``.frames`` (TaxelFrame list), ``.poses`` (PoseSample list), ``.truth``
        (GroundTruth: t s, force N, indentation m) and ``.meta``.

    Raises:
        ValidationError: bad options, or a press the fidelity does not hold (:mod:`palpate.sim.limits`: deeper than
            half the thickness, a Poisson ratio over 0.49 for flex or 0.4999 for the others), naming the limit.
    """
    source, target = press_setup(young, poisson, fidelity, depth, speed, seed, **scene_options)
    return source.press(target)


def check_press_arguments(young, poisson, depth, speed, seed, where: str) -> None:
    """ValidationError naming ``where`` unless young, poisson, speed and depth (or None) are numbers and the seed a
    whole number >= 0 (their ranges are the material's and the target's to check)."""
    for name, value in (("young", young), ("poisson", poisson), ("speed", speed), ("depth", depth)):
        if (value is not None or name != "depth") and (isinstance(value, bool) or not isinstance(value, Real)):
            raise ValidationError(f"{where}: {name} must be a number (SI units), got {value!r}")
    check_seed(seed, f"{where}: seed")


def press_setup(young: float, poisson: float = 0.3, fidelity: str = "rigid", depth: float | None = 0.004,
                speed: float = 0.01, seed: int = 0, *, laws: dict | None = None,
                **scene_options) -> tuple[SimSource, PressTarget]:
    """The fresh source and the target :func:`simulate_press` presses (same arguments; ``laws``: a contact-law
    cache to give the source, see :class:`SimSource`)."""
    check_press_arguments(young, poisson, depth, speed, seed, "simulate_press")
    unknown = sorted(set(scene_options) - set(_OPTIONS))
    if unknown:
        raise ValidationError(f"simulate_press: unknown scene option(s) {unknown}; known: {list(_OPTIONS)}")
    size = float(scene_options.get("size", 0.1))
    thickness = float(scene_options.get("thickness", 0.03))
    mat = Material(scene_options.get("material_name", "material"), young, poisson,
                   float(scene_options.get("damping", 0.0)))
    block = ObjectSpec("block", "box", (size, size, thickness), (0.0, 0.0), mat)
    scene = Scene(
        objects=(block,),
        fingertip=scene_options.get("fingertip", FingertipSpec()),
        taxels=scene_options.get("taxels", TaxelSensorSpec()),
        pose=scene_options.get("pose", PoseSensorSpec()),
    )
    force = scene_options.get("force")
    target = PressTarget(0.0, 0.0, depth=None if force is not None else depth, force=force, speed=speed,
                         hold=float(scene_options.get("hold", 0.0)))
    extra = {k: scene_options[k] for k in ("max_steps", "tolerance", "flex_iterations") if k in scene_options}
    source = SimSource(scene, fidelity=fidelity, seed=seed, variability=scene_options.get("variability", "robot"),
                       timestep=scene_options.get("timestep"), laws=laws, **extra)
    return source, target
