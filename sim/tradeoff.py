"""Speed against accuracy, measured: sweep simulation settings and measure what each costs and what error it adds.

A *setting* is one point of the trade: fidelity (analytic, rigid, flex), physics timestep, the rigid contact
quadrature (footprint rings: the rigid level has no constraint solver, its contact is a tabulated kernel), the flex
cell size, and the taxel sampling rate. For each setting :func:`measure_setting` presses a thick homogeneous block
of each bench material a few times (seeded human-like variability, so the presses of a material differ) and
reports:

- wall time per press-and-release (physics + sensor models, one core) and the real-time factor;
- peak memory of one press (tracemalloc: Python-side allocations, which hold every trace and frame array);
- error against the reference setting (the finest stable one), per press with the same seed: relative error of
  the peak c_P, c_A, c_D and of the fitted n1 and a1 (median over presses);
- force error against the reference mechanics of the bench block (its contact law, which the FE reference
  confirms within ~1%, tests/test_fe_reference.py): relative RMS of F / F_ref(indentation) - 1 over the loading
  phase beyond 0.2 mm;
- leave-one-out accuracy of a haptic memory trained on that setting's presses.

:func:`pareto_front` and :func:`cheapest_within` then pick the settings worth using.
"""

from __future__ import annotations

import time
import tracemalloc
from dataclasses import asdict, dataclass, field

import numpy as np

from palpate.core.errors import FitError, PalpateError, ValidationError
from palpate.core.perception.crossval import leave_one_out
from palpate.core.perception.press import perceive_press
from palpate.core.perception.streams import PressRecording
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Material, ObjectSpec, Scene, TaxelSensorSpec
from palpate.sim.analytic import run_analytic_press
from palpate.sim.contact.stack import object_law
from palpate.sim.controller import HUMAN, press_profile
from palpate.sim.flex.press import run_flex_press
from palpate.sim.rigid import run_rigid_press
from palpate.sim.sensors import ground_truth, sample_poses, sample_taxels
from palpate.sim.stability import MAX_DEPTH_OVER_RADIUS

FIDELITY_ORDER = ("analytic", "rigid", "flex")
#: Bench materials (name, Young's modulus Pa): soft, medium, hard, a decade apart as the thesis' references.
BENCH_MATERIALS = (("soft", 2.0e4), ("medium", 2.0e5), ("hard", 2.0e6))
#: Thick block so Hertz (half-space) applies: 80 x 80 x 40 mm, as the run job's training block.
BENCH_BLOCK = (0.08, 0.08, 0.04)
FEATURES = ("c_P", "c_A", "c_D", "n1", "a1")


@dataclass(frozen=True)
class Setting:
    """One point of the speed/accuracy trade.

    Attributes:
        fidelity: "analytic", "rigid" or "flex".
        timestep: physics step, s (ignored by analytic, which samples at the taxel rate).
        taxel_rate: taxel frame rate, Hz.
        rings: rigid only: polar rings of the contact-force quadrature over the tip footprint.
        resolution: flex only: elastic cell edge, m.
    """

    fidelity: str
    timestep: float = 0.002
    taxel_rate: float = 50.0
    rings: int = 96
    resolution: float = 0.005

    def __post_init__(self) -> None:
        if self.fidelity not in FIDELITY_ORDER:
            raise ValidationError(f"Setting.fidelity must be one of {FIDELITY_ORDER}, got {self.fidelity!r}")
        if not (np.isfinite(self.timestep) and self.timestep > 0):
            raise ValidationError(f"Setting.timestep must be > 0 s, got {self.timestep!r}")
        if not (np.isfinite(self.taxel_rate) and self.taxel_rate > 0):
            raise ValidationError(f"Setting.taxel_rate must be > 0 Hz, got {self.taxel_rate!r}")
        if self.rings < 4:
            raise ValidationError(f"Setting.rings must be >= 4, got {self.rings}")
        if not (np.isfinite(self.resolution) and self.resolution > 0):
            raise ValidationError(f"Setting.resolution must be > 0 m, got {self.resolution!r}")

    @property
    def label(self) -> str:
        """Short human-readable name, e.g. 'rigid dt=2ms rings=96 50Hz'."""
        rate = f"{self.taxel_rate:g}Hz"
        if self.fidelity == "analytic":
            return f"analytic {rate}"
        dt = f"dt={self.timestep * 1e3:g}ms"
        if self.fidelity == "rigid":
            return f"rigid {dt} rings={self.rings} {rate}"
        return f"flex {dt} cell={self.resolution * 1e3:g}mm {rate}"


def finite_or_none(v) -> float | None:
    """A number for a JSON report: None where it is missing or not finite."""
    return None if v is None or not np.isfinite(v) else float(v)


def reference_setting() -> Setting:
    """The finest stable setting of the bench: rigid at 0.25 ms with the full contact quadrature.

    Rigid rather than flex: on a thick homogeneous block both model the same contact, and rigid converges (its
    force is within 1% of the reference mechanics) while flex is limited by its cell size (see the validity table).
    """
    return Setting("rigid", timestep=0.00025, rings=96)


def quick_settings() -> list[Setting]:
    """The CI sweep: a few minutes on two cores."""
    return [
        Setting("analytic", taxel_rate=50.0),
        Setting("analytic", taxel_rate=100.0),
        Setting("rigid", timestep=0.0005),
        Setting("rigid", timestep=0.002),
        Setting("rigid", timestep=0.005),
        Setting("rigid", timestep=0.002, rings=24),
        Setting("rigid", timestep=0.002, taxel_rate=100.0),
        Setting("flex", timestep=0.01, resolution=0.005),
    ]


def full_settings() -> list[Setting]:
    """The workstation sweep: every timestep, quadrature, cell size and rate of the trade."""
    out = [Setting("analytic", taxel_rate=r) for r in (25.0, 50.0, 100.0, 200.0)]
    out += [Setting("rigid", timestep=dt) for dt in (0.0005, 0.001, 0.002, 0.005, 0.01)]
    out += [Setting("rigid", timestep=0.002, rings=r) for r in (12, 24, 48)]
    out += [Setting("rigid", timestep=0.002, taxel_rate=r) for r in (25.0, 100.0, 200.0)]
    # the mesh correction is measured for 5 mm cells; the others run with it extrapolated (said in their meta)
    out += [Setting("flex", timestep=dt, resolution=res) for res in (0.0075, 0.005) for dt in (0.005, 0.01)]
    return out


def bench_scene(young: float, name: str, taxel_rate: float = 50.0) -> tuple[Scene, ObjectSpec]:
    """A thick homogeneous block of one material under the default fingertip, at the given taxel rate."""
    obj = ObjectSpec("block", "box", BENCH_BLOCK, (0.0, 0.0), Material(name, young, 0.3))
    return Scene((obj,), taxels=TaxelSensorSpec(rate=taxel_rate)), obj


def bench_law(young: float, name: str, laws: dict | None = None):
    """The reference mechanics of the bench block of one material: its contact law to 0.75 tip radii."""
    scene, obj = bench_scene(young, name)
    tip = scene.fingertip
    return object_law(obj, 0.0, 0.0, obj.height, tip.radius, MAX_DEPTH_OVER_RADIUS * tip.radius, cache=laws)


def simulate(setting: Setting, young: float, name: str, seed: int, *, depth: float = 0.003,
             speed: float = 0.01, laws: dict | None = None, models: dict | None = None) -> PressRecording:
    """One press-and-release of the bench block at ``setting`` (human-like variability drawn from ``seed``).

    Mirrors :meth:`palpate.sim.source.SimSource.press` but passes the setting's knobs (quadrature, cell size)
    that a SimSource keeps at their defaults; ``laws``/``models`` are caches kept by the caller.
    """

    scene, obj = bench_scene(young, name, setting.taxel_rate)
    tip = scene.fingertip
    target = PressTarget(0.0, 0.0, depth=depth, speed=speed)
    s_profile, s_taxel, s_pose = np.random.SeedSequence([seed, 0]).spawn(3)
    law = bench_law(young, name, laws)
    profile = press_profile(target, obj.height, radius=tip.radius, timestep=min(setting.timestep, 0.002),
                            variability=HUMAN, seed=int(s_profile.generate_state(1)[0]),
                            depth_for_force=law.depth_for_force)
    if setting.fidelity == "analytic":
        trace = run_analytic_press(scene, obj, profile, law=law)
    elif setting.fidelity == "rigid":
        trace = run_rigid_press(scene, obj, profile, timestep=setting.timestep, rings=setting.rings, law=law)
    else:
        trace = run_flex_press(scene, obj, target, profile, timestep=setting.timestep,
                               resolution=setting.resolution, models=models)
    frames = sample_taxels(trace, scene.taxels, tip, np.random.default_rng(s_taxel))
    poses = sample_poses(trace, scene.pose, np.random.default_rng(s_pose))
    meta = {"source": "sim", "fidelity": setting.fidelity, "material": name, "seed": seed,
            "duration": float(trace.t[-1] - trace.t[0])}
    return PressRecording(frames=frames, poses=poses, truth=ground_truth(trace), meta=meta)


@dataclass
class PressMeasure:
    """What one press gave: peak features, fitted (n1, a1), force error against the reference, duration, wall."""

    material: str
    seed: int
    wall: float
    duration: float
    peaks: dict[str, float]
    law_error: float
    params: np.ndarray | None = None


def law_force_error(rec: PressRecording, law, min_depth: float = 2e-4) -> float:
    """Relative RMS of F / F_ref - 1 (``law``: the reference mechanics) over the loading phase beyond
    ``min_depth`` (m); NaN if never that deep."""

    d = np.asarray(rec.truth.indentation)
    f = np.asarray(rec.truth.force)
    loading = (np.arange(len(d)) <= int(np.argmax(d))) & (d > min_depth)
    if not loading.any():
        return float("nan")
    ratio = f[loading] / law.force_at(d[loading]) - 1.0
    return float(np.sqrt(np.mean(ratio**2)))


def measure_press(setting: Setting, young: float, name: str, seed: int, depth: float = 0.003,
                  laws: dict | None = None, models: dict | None = None) -> PressMeasure:
    """Simulate and perceive one press; peaks are NaN where the pipeline found no press or the fit failed."""

    t0 = time.perf_counter()
    rec = simulate(setting, young, name, seed, depth=depth, laws=laws, models=models)
    wall = time.perf_counter() - t0
    res = perceive_press(rec)
    peaks = {k: float("nan") for k in FEATURES}
    if res.press is not None:
        pr = res.press
        peaks.update(c_P=float(np.max(pr.c_P)), c_A=float(np.max(pr.c_A)), c_D=float(np.max(pr.c_D)))
    if res.fit is not None:
        peaks.update(n1=res.fit.n1, a1=res.fit.a1)
    herr = law_force_error(rec, bench_law(young, name, laws))
    return PressMeasure(name, seed, wall, rec.meta["duration"], peaks, herr, res.params)


def peak_memory(setting: Setting, young: float, name: str, seed: int) -> float:
    """Peak Python-side memory of one press-and-release, bytes (tracemalloc)."""
    was = tracemalloc.is_tracing()
    if not was:
        tracemalloc.start()
    tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    try:
        simulate(setting, young, name, seed)
        return float(tracemalloc.get_traced_memory()[1] - base)
    finally:
        if not was:
            tracemalloc.stop()


@dataclass
class SettingResult:
    """The measured cost and error of one setting (errors are fractions; NaN where not measurable)."""

    setting: Setting
    wall_per_press: float = float("nan")
    realtime_factor: float = float("nan")
    peak_memory: float = float("nan")
    errors: dict[str, float] = field(default_factory=dict)
    error: float = float("nan")
    law_error: float = float("nan")
    loo_accuracy: float = float("nan")
    failed: str | None = None
    note: str | None = None
    presses: list[PressMeasure] = field(default_factory=list)

    def to_dict(self) -> dict:
        """JSON-ready row (NaN as None)."""
        num = finite_or_none
        return {
            "label": self.setting.label, "setting": asdict(self.setting),
            "wall_per_press_s": num(self.wall_per_press), "realtime_factor": num(self.realtime_factor),
            "peak_memory_bytes": num(self.peak_memory),
            "errors": {k: num(v) for k, v in self.errors.items()}, "error": num(self.error),
            "force_error_vs_reference": num(self.law_error), "loo_accuracy": num(self.loo_accuracy),
            "failed": self.failed,
            "note": self.note,
        }


def measure_setting(setting: Setting, *, seeds: tuple[int, ...] = (0, 1, 2, 3),
                    materials=BENCH_MATERIALS, memory: bool = True, depth: float = 0.003) -> SettingResult:
    """Press every bench material once per seed at ``setting``; time, memory, Hertz error and LOO accuracy.

    The error against a reference is filled in later by :func:`compare_to_reference`. A setting whose physics
    diverges or is invalid is returned with ``failed`` set (the sweep goes on).
    """

    out = SettingResult(setting)
    laws: dict = {}
    models: dict = {}
    try:
        for name, young in materials:
            for seed in seeds:
                out.presses.append(measure_press(setting, young, name, seed, depth, laws, models))
        if memory:
            name, young = materials[0]
            out.peak_memory = peak_memory(setting, young, name, seeds[0])
    except PalpateError as exc:
        out.failed = f"{type(exc).__name__}: {exc}"
        return out
    walls = np.array([p.wall for p in out.presses])
    durations = np.array([p.duration for p in out.presses])
    out.wall_per_press = float(np.median(walls))
    out.realtime_factor = float(np.sum(durations) / np.sum(walls))
    herr = np.array([p.law_error for p in out.presses])
    out.law_error = float(np.nanmedian(herr)) if np.isfinite(herr).any() else float("nan")
    fitted = [p for p in out.presses if p.params is not None]
    try:
        params = np.array([p.params for p in fitted])
        out.loo_accuracy = leave_one_out(params, [p.material for p in fitted]).accuracy
    except (ValidationError, FitError, np.linalg.LinAlgError) as exc:
        out.note = f"leave-one-out: {exc}"
    return out


def compare_to_reference(result: SettingResult, reference: SettingResult) -> None:
    """Fill ``result.errors`` (median relative error per feature over matching presses) and ``result.error``.

    Presses match by (material, seed). ``error`` is the largest of the per-feature errors: a setting is only
    as good as its worst feature.
    """
    if result.failed or reference.failed:
        return
    ref = {(p.material, p.seed): p.peaks for p in reference.presses}
    rel: dict[str, list[float]] = {k: [] for k in FEATURES}
    for p in result.presses:
        r = ref.get((p.material, p.seed))
        if r is None:
            continue
        for k in FEATURES:
            if np.isfinite(r[k]) and r[k] != 0:
                rel[k].append(abs(p.peaks[k] / r[k] - 1.0) if np.isfinite(p.peaks[k]) else np.inf)
    result.errors = {k: float(np.median(v)) if v else float("nan") for k, v in rel.items()}
    vals = [v for v in result.errors.values() if not np.isnan(v)]
    result.error = float(max(vals)) if vals else float("nan")


def pareto_front(results: list[SettingResult]) -> list[SettingResult]:
    """Settings not beaten by another in both time per press and error (lower is better), fastest first."""
    ok = [r for r in results if r.failed is None and np.isfinite(r.wall_per_press) and np.isfinite(r.error)]
    ok.sort(key=lambda r: (r.wall_per_press, r.error))
    front, best = [], np.inf
    for r in ok:
        if r.error < best:
            front.append(r)
            best = r.error
    return front


def cheapest_within(results: list[SettingResult], tolerance: float) -> SettingResult | None:
    """The fastest setting whose error against the reference is at most ``tolerance`` (fraction), or None."""
    ok = [r for r in results if r.failed is None and np.isfinite(r.error) and r.error <= tolerance]
    return min(ok, key=lambda r: r.wall_per_press) if ok else None


def run_tradeoff(settings: list[Setting], *, reference: Setting | None = None, seeds: tuple[int, ...] = (0, 1, 2, 3),
                 materials=BENCH_MATERIALS, depth: float = 0.003, progress=None, on_start=None) -> dict:
    """Measure every setting and the reference; return {"reference", "results", "pareto", "within_5", "within_1"}.

    ``on_start`` (optional) is called with each Setting (the reference first) before it is measured, ``progress``
    (optional) with each finished SettingResult.
    """
    reference = reference or reference_setting()
    if on_start is not None:
        on_start(reference)
    ref = measure_setting(reference, seeds=seeds, materials=materials, depth=depth)
    if on_start is not None and progress is not None:
        progress(ref)  # the reference's row was opened: close it
    if ref.failed:
        raise ValidationError(f"the reference setting {reference.label} failed: {ref.failed}; choose a finer one")
    compare_to_reference(ref, ref)
    results = []
    for s in settings:
        if on_start is not None and s != reference:
            on_start(s)
        r = ref if s == reference else measure_setting(s, seeds=seeds, materials=materials, depth=depth)
        compare_to_reference(r, ref)
        results.append(r)
        if progress is not None:
            progress(r)
    return {"reference": ref, "results": results, "pareto": pareto_front(results),
            "within_5": cheapest_within(results, 0.05), "within_1": cheapest_within(results, 0.01)}
