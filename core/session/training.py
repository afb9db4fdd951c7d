"""Training: press every reference material, perceive each press, fit the haptic memory and cross-validate it
(seed 000 section 6.8: 3 reference materials x 10 presses, leave-one-out)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from palpate.core.alignment.merge import pipeline_for
from palpate.core.errors import PalpateError, ValidationError
from palpate.core.perception.classifier_memory import ClassifierMemory
from palpate.core.perception.crossval import CrossValidation, leave_one_out
from palpate.core.perception.feature_extractors import extractor_name
from palpate.core.perception.force_channel import with_force_channel
from palpate.core.perception.memory import MIN_SAMPLES, HapticMemory
from palpate.core.perception.press import PressResult, perceive_press
from palpate.core.session.press_log import PressLog
from palpate.core.session.progress import Progress
from palpate.core.session.sources import PressTarget, press_all
from palpate.core.world.scenario import Scenario
from palpate.core.world.scene import ObjectSpec

TRAINING_BLOCK = (0.08, 0.08, 0.04)  # m: a thick sample of each reference material, as in seed 000 Fig. 6.7
#: Fewest fitted presses of a material that training accepts: a 2-D Gaussian needs MIN_SAMPLES, and leave-one-out
#: holds one more out.
MIN_FITTED = MIN_SAMPLES + 1


def run_seeds(scenario: Scenario) -> np.ndarray:
    """The seeds of a run of ``scenario`` (from ``scenario.seed``): 4 spare, then one per reference material (its
    training session, :func:`training_seeds`), then one per object."""
    return np.random.SeedSequence(scenario.seed).generate_state(4 + len(scenario.references) + len(scenario.objects))


def training_seeds(scenario: Scenario) -> np.ndarray:
    """The seed of each reference material's training session in a run of ``scenario``, in reference order."""
    return run_seeds(scenario)[4:4 + len(scenario.references)]


@dataclass(frozen=True)
class TrainingResult:
    """A trained memory, its leave-one-out cross-validation, and every training press as perceived (by material,
    in the scenario's reference order), with its boundary reading when training was given a reader."""

    memory: HapticMemory | ClassifierMemory
    crossval: CrossValidation
    presses: dict[str, tuple[PressResult, ...]]
    readings: dict[str, tuple] = field(default_factory=dict)

    @property
    def dropped(self) -> dict[str, int]:
        """Per material, the presses left out of the memory because no 3/2-power fit was found (their reasons are
        in each press's ``rejected``)."""
        return dropped_presses(self.presses)


def dropped_presses(presses: dict[str, tuple[PressResult, ...]]) -> dict[str, int]:
    """Per material, how many of ``presses`` have no fit (the memory and its tables leave them out)."""
    return {name: sum(r.fit is None for r in rs) for name, rs in presses.items()}


def dropped_message(dropped: dict[str, int], presses_per_material: int) -> str | None:
    """A one-line warning naming the materials that lost presses, or None when none did."""
    lost = [f"{name} {n} of {presses_per_material}" for name, n in dropped.items() if n]
    return None if not lost else ("training: presses dropped because their fit failed: " + ", ".join(lost)
                                  + " (summary.json training_dropped)")


def train_memory(scenario: Scenario, make_source, seeds, progress: Progress,
                 log: PressLog | None = None, classifier: ClassifierMemory | None = None,
                 boundary_reader=None) -> TrainingResult:
    """Press every reference material ``training.presses_per_material`` times on a thick block and fit the memory.

    Args:
        scenario: what to train on (references, training protocol).
        make_source: ``make(objects, seed, variability)``, e.g. from
            :func:`~palpate.core.session.sources.scenario_source_maker`.
        seeds: one seed per reference material.
        progress: progress display.
        log: when given, every press is laid on the run's timeline (and recorded).
        classifier: an unfitted classifier memory (with its feature extractor) to fit instead of the haptic
            memory; it is fitted in place and cross-validated leave-one-out the same way.
        boundary_reader: ``read(recording, result)``: when given, each press's boundary reading is kept too
            (:mod:`palpate.core.session.boundaries`).
    """
    tr = scenario.training
    # an actuator may perceive its presses its own way (options.perception); training perceives alike
    perception = getattr(scenario.actuator.options, "perception", None)
    force = bool(perception) and perception.get("channel") == "force"
    config = pipeline_for(perception) if perception else None
    params, labels, by_material, readings = [], [], {}, {}
    for m, name in enumerate(scenario.references):
        mat = scenario.materials[name].material
        block = ObjectSpec(f"sample_{name}", "box", TRAINING_BLOCK, (0.0, 0.0), mat)
        source = make_source((block,), int(seeds[m]), tr.variability)
        results = []
        progress.start(f"training {name}", tr.presses_per_material)
        # a material's presses are known before any is perceived: a source that batches makes them in one call
        recordings = press_all(source, [PressTarget(0.0, 0.0, depth=tr.depth, force=tr.max_force, speed=tr.speed,
                                                    label=f"{name}#{k + 1}") for k in range(tr.presses_per_material)])
        for k, rec in enumerate(recordings):
            if force:  # the explorer measures a force, not taxels: train on the force it would have measured
                rec = with_force_channel(rec)
            if log is not None:
                rec = log.add(rec, {"phase": "training", "material": name, "k": k + 1})
            res = perceive_press(rec, config)
            results.append(res)
            if boundary_reader is not None:
                readings.setdefault(name, []).append(boundary_reader(rec, res))
            if res.fit is not None:
                params.append(res.fit.params)
                labels.append(name)
            progress.update(k + 1)
        by_material[name] = tuple(results)
        usable = sum(r.fit is not None for r in results)
        if usable < MIN_FITTED:
            raise PalpateError(f"training: only {usable} of {tr.presses_per_material} presses on {name} could be "
                               "fitted; press deeper (training.depth_mm) or lower the taxel threshold")
    readings = {name: tuple(rs) for name, rs in readings.items()}
    if classifier is not None:
        return replace(_train_classifier(classifier, by_material), readings=readings)
    P = np.vstack(params)
    memory = HapticMemory(materials=list(scenario.references), features=config.features if config else "both").fit(
        P, labels)
    crossval = leave_one_out(P, labels, materials=list(scenario.references), features=memory.features)
    return TrainingResult(memory, crossval, by_material, readings)


def _train_classifier(classifier: ClassifierMemory, presses: dict[str, tuple[PressResult, ...]]) -> TrainingResult:
    rows, labels = [], []
    for name, results in presses.items():
        for res in results:
            if res.fit is not None and (x := classifier.press_features(res)) is not None:
                rows.append(x)
                labels.append(name)
    if len({len(x) for x in rows}) > 1:
        raise ValidationError(f"training: feature extractor {extractor_name(classifier.features)!r} gave rows of "
                              f"{sorted({len(x) for x in rows})} values; every press needs the same number")
    X = np.vstack(rows)
    crossval = classifier.crossval(X, labels)
    return TrainingResult(classifier.fit(X, labels), crossval, presses)
