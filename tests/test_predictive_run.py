"""The run's side of the predictive realism check and of dropped presses: the scenario key, the sessions a run
simulates for the check, and training counting the presses whose fit failed."""

from __future__ import annotations

import copy
import csv
import json
from dataclasses import replace

import numpy as np
import pytest

from palpate.core.errors import PalpateError, PressShortfall, ValidationError
from palpate.core.perception.param_stats import STAT_COLUMNS, table_from_csv, table_from_fits
from palpate.core.perception.streams import PressRecording
from palpate.core.session.progress import Progress
from palpate.core.session.sim_to_real import format_predictive, sim_to_real_summary
from palpate.core.session.training import dropped_message, train_memory
from palpate.core.world.scenario_file import parse_scenario

BASE = {
    "scenario": {"name": "tiny", "seed": 4, "fidelity": "analytic"},
    "materials": [{"name": "soft", "young_kpa": 20.0}, {"name": "hard", "young_kpa": 450.0, "poisson": 0.4}],
    "training": {"presses_per_material": 5, "depth_mm": 4.0, "max_force_n": 10.0},
    "exploration": {"policy": "raster", "budget": 2, "depth_mm": 4.0, "max_force_n": 10.0},
    "objects": [{"name": "slab", "size_mm": [20.0, 20.0, 40.0], "position_mm": [10.0, 10.0], "material": "soft"}],
    "outputs": {"figures": False, "haptic_material": False},
}


def _scenario(realism=None, presses=5):
    raw = copy.deepcopy(BASE)
    raw["training"]["presses_per_material"] = presses
    if realism is not None:
        raw["realism"] = realism
    return parse_scenario(raw, "tiny.toml")


def _write_table(path, table):
    with open(path, "w", encoding="utf-8", newline="") as f:
        out = csv.writer(f)
        out.writerow(["material", "run", *STAT_COLUMNS])
        for name in table.materials:
            out.writerows([[name, k + 1, *(repr(float(v)) for v in row)] for k, row in enumerate(table.of(name))])


@pytest.mark.parametrize("realism, match", [
    ({"predictive_sessions": 100}, "predictive_sessions: judges the simulation against a real table"),
    ({"predictive_sessions": 5, "real_params": "REAL"}, "predictive_sessions: must be 0 \\(off\\) or 100-"),
    ({"predictive_sessions": 2.5, "real_params": "REAL"}, "predictive_sessions: expected"),
])
def test_scenario_refuses_a_check_it_cannot_run(tmp_path, realism, match):
    real = tmp_path / "real.csv"
    real.write_text("material,run,n1,n2,phi_n,a1,a2,phi_a\n")
    realism = {k: str(real) if v == "REAL" else v for k, v in realism.items()}
    with pytest.raises(ValidationError, match=match):
        _scenario(realism)


class _Failing:
    """A source whose pad reads nothing (no press to fit) on its presses numbered in ``fail``."""

    press_many = None  # press by press, so that each press passes through press() (training batches otherwise)

    def __init__(self, inner, fail):
        self.inner, self.fail, self.k = inner, fail, 0

    def press(self, target):
        self.k += 1
        rec = self.inner.press(target)
        if self.k not in self.fail:
            return rec
        return PressRecording([replace(f, counts=np.zeros_like(f.counts)) for f in rec.frames], rec.poses, rec.truth,
                              rec.meta)

    def __getattr__(self, name):
        return getattr(self.inner, name)


def test_training_counts_the_presses_whose_fit_failed():
    from palpate.core.session.sources import scenario_source_maker

    sc = _scenario(presses=6)
    make = scenario_source_maker(sc)

    def train(failing):
        return train_memory(sc, lambda objects, s, v: _Failing(make(objects, s, v),
                                                               failing[objects[0].name.removeprefix("sample_")]),
                            [11, 12], Progress(enabled=False))

    result = train({"soft": {2}, "hard": {1, 4}})
    assert result.dropped == {"soft": 1, "hard": 2}
    assert [r.fit is None for r in result.presses["hard"]] == [True, False, False, True, False, False]
    assert result.memory.training_labels == ["soft"] * 5 + ["hard"] * 4  # the memory learnt from the others only
    assert dropped_message(result.dropped, 6) == ("training: presses dropped because their fit failed: soft 1 of 6, "
                                                  "hard 2 of 6 (summary.json training_dropped)")
    assert dropped_message({"soft": 0}, 6) is None
    # three fitted presses make a Gaussian but leave none to hold out: refused, naming what helps
    with pytest.raises(PalpateError, match="only 3 of 6 presses on hard could be fitted; press deeper"):
        train({"soft": set(), "hard": {1, 2, 3}})


@pytest.mark.physics
def test_run_simulates_the_sessions_and_judges_a_table_against_them(tmp_path):
    from palpate.core.perception.predictive_check import MIN_SESSIONS, predictive_check
    from palpate.core.session.predictive import predictive_report, session_seeds, simulate_sessions
    from palpate.core.session.sources import scenario_source_maker

    # "real" presses: one more session of the same simulator (its own seeds), and the same presses with n1 tripled
    sc = _scenario(presses=6)
    make = scenario_source_maker(sc)
    session = train_memory(sc, make, [901, 902], Progress(enabled=False))
    real = table_from_fits({n: [r.fit for r in rs] for n, rs in session.presses.items()})
    real_path = tmp_path / "real.csv"
    _write_table(real_path, real)
    tripled = type(real)(real.materials, tuple(r * np.array([3, 1, 1, 1, 1, 1]) for r in real.rows))

    seeds = session_seeds(sc, MIN_SESSIONS + 1)
    assert seeds.shape == (MIN_SESSIONS + 1, 2) and len({tuple(s) for s in seeds}) == MIN_SESSIONS + 1
    assert np.array_equal(session_seeds(sc, 5), seeds[:5])
    # a session the simulation cannot finish is left out and said
    broken = {int(seeds[3][1])}

    def failing(objects, s, v):
        if s in broken:
            raise PressShortfall("the drive cannot follow this press")
        return make(objects, s, v)

    sim = simulate_sessions(sc, failing, MIN_SESSIONS + 1, Progress(enabled=False))
    assert len(sim.tables) == MIN_SESSIONS and sim.failed == ("the drive cannot follow this press",)
    assert sim.loo.shape == (MIN_SESSIONS, 2) and sim.dropped == {"soft": 0, "hard": 0}
    own = predictive_check(table_from_csv(real_path), sim.tables, sc.references, session_loo=sim.loo)
    assert all(m.energy < float(np.max(m.energy_sessions)) for m in own.materials)
    worse = predictive_check(tripled, sim.tables, sc.references, session_loo=sim.loo)
    assert not worse.passed and not any(worse.material_passed(m) for m in sc.references)
    assert all(not m.energy_passed for m in worse.materials)

    # the run's entry: the check's dict with the sessions' dropped presses and failures; too few left is an error
    sc = _scenario({"real_params": str(real_path), "predictive_sessions": MIN_SESSIONS + 1}, presses=6)
    doc = predictive_report(sc, failing, table_from_csv(real_path), Progress(enabled=False))
    json.dumps(doc, allow_nan=False)
    assert doc["sessions"] == MIN_SESSIONS and doc["failed_sessions"] == ["the drive cannot follow this press"]
    assert doc["passed"] == own.passed and set(doc["materials"]) == {"soft", "hard"}
    summary = sim_to_real_summary(real, table_from_csv(real_path), real_path) | {"predictive_check": doc}
    assert ("PASS" if own.passed else "FAIL") in format_predictive(summary["predictive_check"])
    sc = _scenario({"real_params": str(real_path), "predictive_sessions": MIN_SESSIONS}, presses=6)
    with pytest.raises(ValidationError, match=f"{MIN_SESSIONS - 1} simulated sessions; at least {MIN_SESSIONS}"):
        predictive_report(sc, failing, table_from_csv(real_path), Progress(enabled=False))
