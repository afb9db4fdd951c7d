"""Realism profiles: presets, files validated on load (errors name file and key), names resolved, and the ideal
profile replaying the simulation exactly as without profiles."""

import contextlib
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.session.sources import PressTarget
from palpate.core.world.scenario_file import load_scenario
from palpate.core.world.scene import Material, ObjectSpec, Scene
from palpate.sim.controller import HUMAN
from palpate.sim.realism.profile import IDEAL, LAB, PRESETS, RealismProfile, TaxelRealism
from palpate.sim.realism.profile_file import (
    load_profile,
    parse_profile,
    profile_to_toml,
    resolve_profile,
    shipped_profiles,
)
from palpate.sim.source import SimSource

REPO = Path(__file__).resolve().parent.parent


@contextlib.contextmanager
def limits_lowered(assignment: str):
    """A limit lowered for the block (palpate --limit NAME=VALUE)."""
    import os

    from palpate.core.limits import ENV

    before = os.environ.get(ENV)
    os.environ[ENV] = assignment
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(ENV, None)
        else:
            os.environ[ENV] = before


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_presets_round_trip_through_their_file(name, tmp_path):
    path = tmp_path / f"{name}.toml"
    path.write_text(profile_to_toml(PRESETS[name]))
    assert load_profile(path) == PRESETS[name]


def test_only_ideal_is_ideal_and_it_is_todays_human_press():
    assert IDEAL.is_ideal and IDEAL.press == HUMAN
    assert not any(p.is_ideal for n, p in PRESETS.items() if n != "ideal")
    # a profile that changes one thing is no longer ideal
    assert not replace(IDEAL, taxels=TaxelRealism(sensitivity=2.0)).is_ideal


def test_a_file_lists_only_what_departs_from_ideal():
    p = parse_profile({"taxels": {"creep": 0.02}}, "x.toml", "x")
    assert p.name == "x" and p.taxels.creep == 0.02
    assert replace(p, name="ideal", description=IDEAL.description, taxels=IDEAL.taxels) == IDEAL


@pytest.mark.parametrize("doc, key", [
    ({"taxels": {"creeep": 0.1}}, "taxels.creeep"),
    ({"finger": {"stiffness_n_per_mm": -1.0}}, "finger.stiffness_n_per_mm"),
    ({"finger": {"compliant": "yes"}}, "finger.compliant"),
    ({"press": {"tilt_deg": 45.0}}, "press.tilt_deg"),
    ({"taxels": {"activation_kpa": -1.0}}, "taxels.activation_kpa"),
    ({"taxels": {"activation_cv": 3.5}}, "taxels.activation_cv"),
    ({"finger": {"pressure_exponent": 0.2}}, "finger.pressure_exponent"),
    ({"press": {"speed_cv": 0.7}}, "press.speed_cv"),
    ({"press": {"push_force_n": -0.5}}, "press.push_force_n"),
    ({"press": {"push_depth_scale": 0.5}}, "press.push_depth_scale"),
    ({"press": {"push_stiffness_n_per_mm": -1.0}}, "press.push_stiffness_n_per_mm"),
    ({"pose": {"latency_ms": "3"}}, "pose.latency_ms"),
    ({"material": {"relaxation_time_s": 0.0}}, "material.relaxation_time_s"),
    ({"provenance": {"x": {"y": [1.0, {"z": 1}]}}}, "provenance.x.y"),
    ({"unknown_table": {}}, "unknown_table"),
])
def test_bad_values_name_the_file_and_the_key(doc, key):
    with pytest.raises(ValidationError, match=rf"bad\.toml: {key.replace('.', '[.]')}"):
        parse_profile(doc, "bad.toml")


def test_values_out_of_the_models_range_are_refused_with_the_file_named():
    with pytest.raises(ValidationError, match=r"bad\.toml: .*relaxation"):
        parse_profile({"material": {"relaxation": 0.99}}, "bad.toml")


def test_unreadable_files_are_refused_before_parsing(tmp_path):
    with pytest.raises(ValidationError, match="not found"):
        load_profile(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[finger\ncompliant = true\n")
    with pytest.raises(ValidationError, match=r"bad\.toml: not valid TOML"):
        load_profile(bad)
    big = tmp_path / "big.toml"
    big.write_bytes(b"#" * 2_000_001)
    with pytest.raises(ValidationError, match="text_mb"):
        with limits_lowered("text_mb=2"):
            load_profile(big)
    binary = tmp_path / "bin.toml"
    binary.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ValidationError, match="UTF-8"):
        load_profile(binary)


def test_names_resolve_to_presets_shipped_profiles_and_paths(tmp_path):
    assert resolve_profile(None) is IDEAL
    assert resolve_profile("lab") is LAB
    assert "thesis_ch6" in shipped_profiles()
    fitted = resolve_profile("thesis_ch6")
    assert isinstance(fitted, RealismProfile) and not fitted.is_ideal
    assert fitted.provenance["table"] == "seed000_tables_6_3_to_6_5.csv"
    path = tmp_path / "mine.toml"
    path.write_text(profile_to_toml(replace(LAB, name="mine")))
    assert resolve_profile(str(path)).name == "mine"
    with pytest.raises(ValidationError, match="unknown realism profile 'labb'.*ideal, sensors, lab"):
        resolve_profile("labb")


def test_every_shipped_profile_loads_and_round_trips():
    for name in shipped_profiles():
        p = resolve_profile(name)
        assert parse_profile(tomllib.loads(profile_to_toml(p)), "again", name) == p


def test_scenario_realism_key_is_validated(tmp_path):
    text = (REPO / "scenarios" / "thesis_ch6.toml").read_text()
    assert 'profile = "thesis_ch6"' in text
    bad = tmp_path / "s.toml"
    bad.write_text(text.replace('profile = "thesis_ch6"', 'profile = "nowhere/x.toml"'))
    with pytest.raises(ValidationError, match=r"s\.toml: realism\.profile: realism profile file .* not found"):
        load_scenario(bad)
    bad.write_text(text.replace("[realism]", "[realism]\nprofiles = 1"))
    with pytest.raises(ValidationError, match=r"s\.toml: realism\.profiles: unknown key"):
        load_scenario(bad)
    scenario = load_scenario(REPO / "scenarios" / "thesis_ch6.toml")
    assert scenario.realism.profile == "thesis_ch6"
    assert scenario.realism.real_params.name == "seed000_tables_6_3_to_6_5.csv"


def _presses(realism, n=2, variability="human"):
    block = ObjectSpec("b", "box", (0.08, 0.08, 0.04), (0.0, 0.0), Material("m", 60e3, 0.4))
    src = SimSource(Scene((block,)), fidelity="analytic", seed=3, variability=variability, realism=realism)
    return [src.press(PressTarget(0.0, 0.0, depth=0.004, force=8.0, speed=0.01)) for _ in range(n)]


def test_ideal_profile_replays_the_simulation_exactly():
    for a, b in zip(_presses(None), _presses("ideal"), strict=True):
        np.testing.assert_array_equal([f.counts for f in a.frames], [f.counts for f in b.frames])
        np.testing.assert_array_equal([p.position for p in a.poses], [p.position for p in b.poses])
        assert [f.t for f in a.frames] == [f.t for f in b.frames]
        assert "realism" not in b.meta


def test_a_profile_changes_the_streams_and_says_what_it_drew():
    a, b = _presses("ideal", 1)[0], _presses("lab", 1)[0]
    c_p = [sum(int(f.counts.sum()) for f in rec.frames) for rec in (a, b)]
    assert c_p[0] != c_p[1]
    assert b.meta["realism"]["profile"] == "lab"
    assert b.meta["realism"]["pulp_stiffness_scale"] > 0


def test_ideal_keeps_todays_numbers():
    """The fits of two human-like analytic presses as the simulation gave them before realism profiles existed
    (commit afd7437; re-pinned at 9a52b9f, where analytic gained the finite-thickness contact law, before it
    was merged with the profiles). If the contact mechanics change on purpose, these numbers change with
    them; the ideal profile itself must never change them."""
    from palpate.core.perception.press import perceive_press
    from palpate.sim import simulate_press

    before = {0: [60.0071581894012, -8.863934335586578, 0.6403540086566494, -36.80801709134147],
              1: [55.68380594167512, -21.510101074362865, 0.6779398343524139, -45.325288109851556]}
    for seed, params in before.items():
        fit = perceive_press(simulate_press(60e3, 0.4, fidelity="analytic", depth=0.004, seed=seed,
                                            variability="human")).fit
        np.testing.assert_allclose([fit.n1, fit.n2, fit.a1, fit.a2], params, rtol=1e-9)
