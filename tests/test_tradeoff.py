"""sim/tradeoff: the speed/accuracy measurement (Pareto front, cheapest setting, errors against the reference
setting and the reference mechanics)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.sim import tradeoff as T
from palpate.sim import tradeoff_report as TR


def _result(label_dt: float, wall: float, err: float) -> T.SettingResult:
    return T.SettingResult(T.Setting("rigid", timestep=label_dt), wall_per_press=wall, error=err)


def test_pareto_front_and_cheapest_within_tolerance():
    a, b, c, d = _result(1e-3, 0.01, 0.20), _result(2e-3, 0.02, 0.03), _result(3e-3, 0.03, 0.05), \
        _result(4e-3, 0.05, 0.004)
    failed = _result(5e-3, 0.001, 0.0)
    failed.failed = "SimulationDiverged: x"
    front = T.pareto_front([a, b, c, d, failed])
    assert front == [a, b, d]  # c is slower and worse than b; a failed setting is never chosen
    assert T.cheapest_within([a, b, c, d, failed], 0.05) is b
    assert T.cheapest_within([a, b, c, d, failed], 0.01) is d
    assert T.cheapest_within([a, b, c], 0.001) is None


def test_bad_setting_names_the_field():
    with pytest.raises(ValidationError, match="fidelity"):
        T.Setting("voxel")
    with pytest.raises(ValidationError, match="timestep"):
        T.Setting("rigid", timestep=0.0)
    with pytest.raises(ValidationError, match="taxel_rate"):
        T.Setting("rigid", taxel_rate=float("nan"))


def test_analytic_is_the_contact_law_and_rigid_converges_to_its_reference():
    mats = T.BENCH_MATERIALS[:2]
    ana = T.measure_setting(T.Setting("analytic"), seeds=(0,), materials=mats, memory=False)
    assert ana.failed is None and ana.law_error < 1e-9  # the closed form is the law by construction
    ref = T.measure_setting(T.Setting("rigid", timestep=0.0005), seeds=(0,), materials=mats, memory=False)
    coarse = T.measure_setting(T.Setting("rigid", timestep=0.005), seeds=(0,), materials=mats, memory=False)
    T.compare_to_reference(coarse, ref)
    T.compare_to_reference(ref, ref)
    assert ref.error == 0.0
    assert coarse.error < 0.01
    # rigid's force is the law on the footprint (quadrature) reached by a drive that tracks (feedforward)
    assert ref.law_error < 0.01
    # with the drive tracking its setpoint, the analytic level's features agree with rigid's (the worst, the
    # cutaneous slope a1 from 4x4 sensel areas, within 10%)
    T.compare_to_reference(ana, ref)
    assert ana.error < 0.10


def test_report_json_and_table(tmp_path):
    mats = T.BENCH_MATERIALS[:2]
    report = T.run_tradeoff([T.Setting("analytic"), T.Setting("rigid", timestep=0.005)],
                            reference=T.Setting("rigid", timestep=0.001), seeds=(0, 1, 2, 3, 4), materials=mats)
    doc = json.loads(json.dumps(TR.report_to_dict(report), allow_nan=False))
    assert [r["label"] for r in doc["results"]] == ["analytic 50Hz", "rigid dt=5ms rings=96 50Hz"]
    assert doc["cheapest_within_5pct"] == "analytic 50Hz"
    assert all(0.0 <= r["loo_accuracy"] <= 1.0 for r in doc["results"])
    assert report["results"][1].realtime_factor > 1.0 and np.isfinite(report["results"][1].peak_memory)
    table = TR.format_table(report)
    assert "cheapest within 5% of the reference: analytic 50Hz" in table
    TR.pareto_plot(report, tmp_path / "p.png")
    assert (tmp_path / "p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_one_law_cache_serves_blocks_that_share_a_name_and_place_but_not_a_modulus():
    """The bench presses blocks of three moduli under one name and place with one law cache: the edge of its block
    is within reach, so the law is cached by place, and a block ten times stiffer must still push ten times harder
    (same geometry and Poisson ratio: force is proportional to E)."""
    laws: dict = {}
    forces = [T.bench_law(young, name, laws).force_at(np.array([0.001, 0.003])) for name, young in T.BENCH_MATERIALS]
    for (_, y0), (_, y1), f0, f1 in zip(T.BENCH_MATERIALS, T.BENCH_MATERIALS[1:], forces, forces[1:],
                                         strict=False):
        np.testing.assert_allclose(f1 / f0, y1 / y0, rtol=1e-6)
    again = T.bench_law(T.BENCH_MATERIALS[0][1], T.BENCH_MATERIALS[0][0], laws)
    assert again is T.bench_law(T.BENCH_MATERIALS[0][1], T.BENCH_MATERIALS[0][0], laws)  # still a cache hit
    np.testing.assert_allclose(again.force_at(np.array([0.001, 0.003])), forces[0])
