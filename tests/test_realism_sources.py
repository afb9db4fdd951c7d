"""Each source of variability of a realism profile changes the streams and features in the direction physics says,
checked against closed forms where one exists."""

from dataclasses import replace

import numpy as np
import pytest

from palpate.core.errors import ValidationError
from palpate.core.perception.press import perceive_press
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Material, ObjectSpec, PoseSensorSpec, Scene, TaxelSensorSpec
from palpate.sim.controller import ROBOT, press_profile, stiff_depth
from palpate.sim.hertz import hertz_depth_for_force
from palpate.sim.realism.finger import series_law
from palpate.sim.realism.material import relax_force
from palpate.sim.realism.profile import IDEAL, FingerPulp, MaterialRealism, PoseRealism, TaxelRealism
from palpate.sim.realism.taxels import TaxelResponse, _running_peak, gain_map
from palpate.sim.sensors import sample_poses
from palpate.sim.source import SimSource
from palpate.sim.trace import PhysicsTrace

QUIET_TAXELS = TaxelSensorSpec(noise_std=0.0)
QUIET_POSE = PoseSensorSpec(noise_std=0.0, jitter=0.0)


def _source(young, profile, seed=1, variability="robot", poisson=0.4):
    block = ObjectSpec("b", "box", (0.08, 0.08, 0.04), (0.0, 0.0), Material("m", young, poisson))
    scene = Scene((block,), taxels=QUIET_TAXELS, pose=QUIET_POSE)
    return SimSource(scene, fidelity="analytic", seed=seed, variability=variability, realism=profile)


def _pulp(stiffness_n_per_m):
    return replace(IDEAL, name="pulp", finger=FingerPulp(compliant=True, stiffness=stiffness_n_per_m,
                                                         stiffening=1000.0, area_factor=2.0))


def _n1(young, profile, depth=0.004):
    return perceive_press(_source(young, profile).press(PressTarget(0.0, 0.0, depth=depth, speed=0.01))).fit.n1


def test_a_softer_finger_lowers_n1_on_hard_materials_more_than_on_soft_ones():
    soft, hard = 20e3, 450e3
    loss_soft = _n1(soft, _pulp(300.0)) / _n1(soft, _pulp(3000.0))
    loss_hard = _n1(hard, _pulp(300.0)) / _n1(hard, _pulp(3000.0))
    assert loss_hard < loss_soft < 1.0
    # and a rigid finger is the stiffest of all
    assert _n1(hard, IDEAL) > _n1(hard, _pulp(3000.0))


def test_the_bone_moves_the_objects_indentation_plus_the_pulps_closed_form_compression():
    pulp = FingerPulp(compliant=True, stiffness=400.0, stiffening=1500.0, area_factor=2.0)
    rec = _source(200e3, replace(IDEAL, finger=pulp)).press(PressTarget(0.0, 0.0, depth=0.004, speed=0.01))
    t = np.array([p.t for p in rec.poses])
    z = np.array([p.position[2] for p in rec.poses])
    k = int(np.argmin(z))
    bone_travel = (z[0] - 0.002) - z[k]  # from the start height less the approach gap to the deepest sample
    force = np.interp(t[k], rec.truth.t, rec.truth.force)
    indentation = np.interp(t[k], rec.truth.t, rec.truth.indentation)
    serina = np.log1p(1500.0 * force / 400.0) / 1500.0  # F = b/m (e^{m delta} - 1), solved for delta
    assert bone_travel == pytest.approx(indentation + serina, rel=2e-3)
    assert serina > 0.2 * bone_travel  # the pulp took a real share of the movement


def test_the_series_law_splits_the_bone_travel_by_force_balance():
    pulp = FingerPulp(compliant=True, stiffness=500.0, stiffening=1000.0)
    e_star, radius = 300e3, 0.008
    law = series_law(e_star, radius, pulp, 1.0, reach=0.006)
    d = law.object_depth_at(np.array([0.004]))[0]
    f_object = 4.0 / 3.0 * e_star * np.sqrt(radius) * d**1.5  # Hertz
    assert d + pulp.compression(f_object) == pytest.approx(0.004, rel=1e-3)


def _hold_press(taxels, hold=2.0, young=100e3):
    prof = replace(IDEAL, name="t", taxels=taxels)
    rec = _source(young, prof).press(PressTarget(0.0, 0.0, depth=0.003, speed=0.01, hold=hold))
    t = np.array([f.t for f in rec.frames])
    c_p = np.array([f.counts.sum() for f in rec.frames], dtype=float)
    return rec, t, c_p


def test_creep_makes_c_p_rise_during_a_hold():
    rec, t, c_p = _hold_press(TaxelRealism(creep=0.05))
    t0, t1 = rec.meta["phases"]["hold"]
    hold = (t > t0 + 0.1) & (t < t1 - 0.05)
    rise = c_p[hold][-1] - c_p[hold][0]
    assert rise > 0.02 * c_p[hold][0]
    _, t_ideal, c_ideal = _hold_press(TaxelRealism(creep=0.0))
    assert c_ideal[hold].max() - c_ideal[hold].min() <= 0.002 * c_ideal[hold].max() + 2


def test_hysteresis_makes_unloading_read_higher_than_loading_at_the_same_force():
    def branches(h):
        rec, t, c_p = _hold_press(TaxelRealism(hysteresis=h), hold=0.0)
        force = np.interp(t, rec.truth.t, rec.truth.force)
        peak = int(np.argmax(force))
        levels = np.linspace(0.2, 0.8, 7) * force[peak]
        load = np.interp(levels, force[:peak + 1], c_p[:peak + 1])
        unload = np.interp(levels, force[peak:][::-1], c_p[peak:][::-1])
        return load, unload

    load, unload = branches(0.15)
    assert np.all(unload > load + 1)
    load0, unload0 = branches(0.0)
    np.testing.assert_allclose(unload0, load0, rtol=0.02, atol=2)


def test_the_taxel_response_closed_forms():
    t = np.linspace(0.0, 1.0, 11)
    p = np.zeros((11, 3, 3))
    p[:, 1, 1] = 1000.0
    fs = 255.0 / 1.2e-3
    # crosstalk: each neighbour reads its share of the loaded sensel, corners nothing
    out = TaxelResponse(TaxelRealism(crosstalk=0.05), np.ones((3, 3)), fs)(t, p)
    assert out[0, 0, 1] == pytest.approx(50.0) and out[0, 0, 0] == 0.0 and out[0, 1, 1] == pytest.approx(1000.0)
    # non-linearity: y / (1 + k y / full scale); sensitivity: a factor
    out = TaxelResponse(TaxelRealism(nonlinearity=0.5, sensitivity=2.0), np.ones((3, 3)), fs)(t, p)
    assert out[0, 1, 1] == pytest.approx(2000.0 / (1.0 + 0.5 * 2000.0 / fs))
    # creep: 1 + c log10(1 + t_loaded / 1 s), the clock restarting when the sensel unloads
    p2 = p.copy()
    p2[5, 1, 1] = 0.0
    out = TaxelResponse(TaxelRealism(creep=0.1), np.ones((3, 3)), fs)(t, p2)
    assert out[4, 1, 1] == pytest.approx(1000.0 * (1 + 0.1 * np.log10(1.4)))
    assert out[6, 1, 1] == pytest.approx(1000.0 * (1 + 0.1 * np.log10(1.1)))
    # activation: silent below the turn-on pressure, the whole pressure above it (a step, not a dead band)
    assert np.all(TaxelResponse(TaxelRealism(activation=1500.0), np.ones((3, 3)), fs)(t, p) == 0.0)
    out = TaxelResponse(TaxelRealism(activation=500.0, sensitivity=2.0), np.ones((3, 3)), fs)(t, p)
    assert out[0, 1, 1] == pytest.approx(2000.0) and out[0, 0, 1] == 0.0


def _a_fit(young, profile, depth=0.004):
    return perceive_press(_source(young, profile).press(PressTarget(0.0, 0.0, depth=depth, speed=0.01))).fit


def test_a_turn_on_pressure_raises_a1_and_a2_on_soft_materials_more_than_on_stiff_ones():
    # Hertz's pressure falls to 0 at the patch's rim and its peak grows with the modulus, so a sensel's turn-on
    # pressure silences covered sensels mostly on soft foam: fewer active sensels for the same intensity there, and
    # a positive offset (seed 000: the sponge's a1 is the rubber's, 3.0 vs 2.9, and its a2 > 0 in every press)
    soft, stiff = 8e3, 80e3
    plain = replace(IDEAL, name="pad", taxels=TaxelRealism(sensitivity=8.0))  # count threshold ~0.3 kPa
    pad = replace(plain, taxels=TaxelRealism(sensitivity=8.0, activation=2000.0))
    fits = {(e, p.taxels.activation): _a_fit(e, p, depth=0.005) for e in (soft, stiff) for p in (plain, pad)}
    gain_soft = fits[soft, 2000.0].a1 / fits[soft, 0.0].a1
    gain_stiff = fits[stiff, 2000.0].a1 / fits[stiff, 0.0].a1
    assert gain_soft > 1.1 > gain_stiff
    assert fits[soft, 0.0].a2 < 0 < fits[soft, 2000.0].a2


def test_gain_spread_is_a_mean_one_map_with_the_asked_spread(rng):
    g = gain_map(TaxelRealism(gain_spread=0.1), (200, 200), rng)
    assert g.mean() == pytest.approx(1.0, abs=0.005)
    assert g.std() == pytest.approx(0.1, rel=0.05)
    assert np.all(gain_map(TaxelRealism(), (4, 4), rng) == 1.0)


def test_relaxation_matches_the_standard_linear_solid_under_a_ramp_and_hold():
    g, tau, k, ramp = 0.3, 0.4, 10.0, 0.5
    t = np.linspace(0.0, 2.0, 4001)
    elastic = k * np.minimum(t, ramp)
    f = relax_force(t, elastic, g, tau)
    expected = np.where(
        t <= ramp,
        (1 - g) * k * t + g * k * tau * (1 - np.exp(-t / tau)),
        (1 - g) * k * ramp + g * k * tau * (1 - np.exp(-ramp / tau)) * np.exp(-(t - ramp) / tau),
    )
    np.testing.assert_allclose(f, expected, atol=1e-9 * k)


def test_viscoelastic_materials_are_stiffer_when_pressed_faster():
    prof = replace(IDEAL, name="ve", material=MaterialRealism(relaxation=0.3, relaxation_time=0.3))

    def n1(speed):
        rec = _source(60e3, prof).press(PressTarget(0.0, 0.0, depth=0.004, speed=speed))
        return perceive_press(rec).fit.n1

    assert n1(0.03) > 1.05 * n1(0.005)


def test_repeated_presses_at_one_spot_soften_the_material():
    prof = replace(IDEAL, name="soft", material=MaterialRealism(softening=0.2, softening_presses=2.0))
    src = _source(60e3, prof)
    n1 = [perceive_press(src.press(PressTarget(0.0, 0.0, depth=0.004, speed=0.01))).fit.n1 for _ in range(4)]
    assert n1[0] > n1[1] > n1[2] > n1[3]
    assert n1[3] / n1[0] == pytest.approx(1 - 0.2 * (1 - np.exp(-3 / 2.0)), rel=0.03)
    # softening stays where the presses were: a press 28 mm away feels what a fresh block feels there (the block's
    # sides, 20 mm from that point, make both a little softer than the centre)
    elsewhere = perceive_press(src.press(PressTarget(0.02, 0.02, depth=0.004, speed=0.01))).fit.n1
    fresh = perceive_press(_source(60e3, prof).press(PressTarget(0.02, 0.02, depth=0.004, speed=0.01))).fit.n1
    assert elsewhere == pytest.approx(fresh, rel=0.03)


def test_tracker_latency_shows_the_finger_where_it_was():
    n = 2001
    t = np.linspace(0.0, 2.0, n)
    pos = np.column_stack([np.zeros(n), np.zeros(n), 0.05 - 0.01 * t])
    trace = PhysicsTrace(t, pos, np.tile([1.0, 0, 0, 0], (n, 1)), np.zeros((n, 4, 4)), np.zeros(n), np.zeros(n), 0.0)
    poses = sample_poses(trace, QUIET_POSE, np.random.default_rng(0), latency=0.05)
    k = len(poses) // 2
    assert poses[k].position[2] == pytest.approx(0.05 - 0.01 * (poses[k].t - 0.05), abs=1e-9)


def test_the_ntp_offset_is_drawn_per_session_and_wanders_per_press():
    prof = replace(IDEAL, name="clock", pose=PoseRealism(clock_offset_std=0.01, clock_wander=0.002))
    offsets = []
    for seed in range(40):
        src = _source(60e3, prof, seed=seed)
        per_press = [src.press(PressTarget(0.0, 0.0, depth=0.002, speed=0.02)).meta["realism"]["pose_clock_offset_s"]
                     for _ in range(2)]
        offsets.append(per_press)
    offsets = np.array(offsets)
    assert np.std(offsets[:, 0]) == pytest.approx(0.01, rel=0.35)
    assert 0 < np.std(offsets[:, 1] - offsets[:, 0]) < 0.006


def test_tilt_moves_the_contact_on_the_pad_and_slip_moves_the_bone_sideways():
    prof = replace(IDEAL, name="tilt", press=replace(ROBOT, tilt_std=np.deg2rad(8.0), slip_std=0.2))
    centroids, drift = [], []
    for seed in range(6):
        # "human": the profile's press (here a robot's, tilted and slipping)
        rec = _source(60e3, prof, seed=seed, variability="human").press(PressTarget(0.0, 0.0, depth=0.004, speed=0.01))
        tilt = np.asarray(rec.meta["profile"]["tilt"])
        slip = np.asarray(rec.meta["profile"]["slip"])
        counts = np.array([f.counts for f in rec.frames], dtype=float).sum(axis=0)
        cols = np.arange(4) - 1.5
        cx = (counts.sum(axis=0) * cols).sum() / counts.sum()
        cy = -(counts.sum(axis=1) * cols).sum() / counts.sum()  # row 0 is at +y
        centroids.append(((cx, cy), tilt))
        z = np.array([p.position[2] for p in rec.poses])
        xy = np.array([p.position[:2] for p in rec.poses])
        k = int(np.argmin(z))
        drift.append((xy[k] - xy[0], slip, (z[0] - 0.002) - z[k]))
    for (cx, cy), tilt in centroids:
        assert np.sign(cx) == np.sign(tilt[0]) and np.sign(cy) == np.sign(tilt[1])
    for moved, slip, travel in drift:
        np.testing.assert_allclose(moved, slip * travel, rtol=0.02, atol=1e-6)


def test_tremor_oscillates_in_the_physiological_band_with_its_amplitude():
    target = PressTarget(0.0, 0.0, depth=0.004, speed=0.005, hold=1.0)
    calm = press_profile(target, 0.04, radius=0.008, timestep=0.001, variability=ROBOT, seed=4)
    shaky = press_profile(target, 0.04, radius=0.008, timestep=0.001, variability=replace(ROBOT, tremor=1e-4),
                          seed=4)
    wobble = shaky.z - calm.z
    assert np.max(np.abs(wobble)) == pytest.approx(1e-4, rel=0.05)
    spectrum = np.abs(np.fft.rfft(wobble))
    freq = np.fft.rfftfreq(len(wobble), 0.001)
    assert 8.0 <= freq[np.argmax(spectrum)] <= 12.0
    assert shaky.z[0] == calm.z[0] and shaky.z[-1] == pytest.approx(calm.z[-1])


def _hertz_depth_for_force(e_star: float, radius: float = 0.008):
    """Hertz's indentation, m, for a force, N, on a block of plane-strain modulus e_star, Pa."""
    return lambda f: hertz_depth_for_force(e_star, radius, f)


def _bottom_depth(profile) -> float:
    return float(profile.surface_z + profile.meta["radius"] - profile.z.min())


def test_a_person_presses_a_soft_object_on_until_it_pushes_back_within_the_cap():
    target = PressTarget(0.0, 0.0, depth=2.5e-3, force=10.0, speed=0.01)
    kw = dict(radius=0.008, timestep=0.001, seed=3)
    soft, stiff = _hertz_depth_for_force(10e3), _hertz_depth_for_force(500e3)
    person = replace(ROBOT, push_force=1.0, push_depth_scale=2.0)
    # a robot stops at the depth whatever the material
    assert _bottom_depth(press_profile(target, 0.04, variability=ROBOT, depth_for_force=soft, **kw)) == \
        pytest.approx(2.5e-3)
    # on 500 kPa 2.5 mm already carries more than 1 N: the person stops at the depth too
    assert stiff(1.0) < 2.5e-3
    assert _bottom_depth(press_profile(target, 0.04, variability=person, depth_for_force=stiff, **kw)) == \
        pytest.approx(2.5e-3)
    # on 10 kPa 1 N needs more than twice the depth: the press goes on to the cap
    assert soft(1.0) > 5e-3
    assert _bottom_depth(press_profile(target, 0.04, variability=person, depth_for_force=soft, **kw)) == \
        pytest.approx(5e-3)
    # a wider cap lets the same press go deeper into the soft block, not into the stiff one
    wider = replace(person, push_depth_scale=3.0)
    assert soft(1.0) > 7.5e-3
    assert _bottom_depth(press_profile(target, 0.04, variability=wider, depth_for_force=soft, **kw)) == \
        pytest.approx(7.5e-3)
    assert _bottom_depth(press_profile(target, 0.04, variability=wider, depth_for_force=stiff, **kw)) == \
        pytest.approx(2.5e-3)
    # where the push force is reached inside the cap, the press stops there
    mid = _hertz_depth_for_force(20e3)
    assert 2.5e-3 < mid(0.4) < 5e-3
    got = press_profile(target, 0.04, variability=replace(person, push_force=0.4), depth_for_force=mid, **kw)
    assert _bottom_depth(got) == pytest.approx(mid(0.4))
    # the force limit still stops a press first
    capped = press_profile(PressTarget(0.0, 0.0, depth=2.5e-3, force=0.2, speed=0.01), 0.04, variability=person,
                           depth_for_force=soft, **kw)
    assert _bottom_depth(capped) == pytest.approx(soft(0.2))


def test_the_depth_at_which_a_hertz_block_gets_this_stiff_is_hertz_s():
    # F = K d^1.5 has dF/dd = 1.5 K sqrt(d): it reaches k at d = (k / 1.5 K)^2
    radius = 0.008
    for e_star in (20e3, 300e3):
        big_k = 4.0 / 3.0 * e_star * np.sqrt(radius)
        for k in (300.0, 1000.0):
            assert stiff_depth(_hertz_depth_for_force(e_star, radius), k) == \
                pytest.approx((k / (1.5 * big_k)) ** 2, rel=0.01)
    # a law that never gets that stiff leaves the press to its cap
    assert stiff_depth(lambda f: f / 100.0, 1000.0) == float("inf")


def test_a_person_presses_on_until_the_object_feels_stiff_a_sponge_deeper_than_a_rubber():
    target = PressTarget(0.0, 0.0, depth=1.6e-3, force=10.0, speed=0.01)
    kw = dict(radius=0.008, timestep=0.001, seed=3)
    person = replace(ROBOT, push_stiffness=1000.0, push_depth_scale=3.0)
    soft, stiff = _hertz_depth_for_force(10e3), _hertz_depth_for_force(500e3)
    # the stiff block is stiffer than 1 N/mm before 1.6 mm: the person stops at the depth, as a robot does
    assert stiff_depth(stiff, 1000.0) < 1.6e-3
    assert _bottom_depth(press_profile(target, 0.04, variability=person, depth_for_force=stiff, **kw)) == \
        pytest.approx(1.6e-3)
    # the soft one only gets that stiff past the cap: the press goes on to the cap
    assert stiff_depth(soft, 1000.0) > 4.8e-3
    assert _bottom_depth(press_profile(target, 0.04, variability=person, depth_for_force=soft, **kw)) == \
        pytest.approx(4.8e-3)
    # between them, the press stops where the object gets that stiff, deeper the softer the object
    stops = []
    for e_star in (100e3, 130e3):
        law = _hertz_depth_for_force(e_star)
        got = _bottom_depth(press_profile(target, 0.04, variability=person, depth_for_force=law, **kw))
        assert 1.6e-3 < got < 4.8e-3 and got == pytest.approx(stiff_depth(law, 1000.0))
        stops.append(got)
    assert stops[0] > stops[1]
    # a stiffer stop threshold presses deeper; with a push force too the press goes on until both are reached
    law = _hertz_depth_for_force(130e3)
    firmer = _bottom_depth(press_profile(target, 0.04, variability=replace(person, push_stiffness=1200.0),
                                         depth_for_force=law, **kw))
    assert firmer > stops[1]
    both = press_profile(target, 0.04, variability=replace(person, push_force=2.0), depth_for_force=law, **kw)
    assert law(2.0) > stops[1] and _bottom_depth(both) == pytest.approx(min(law(2.0), 4.8e-3))
    # the force limit still stops a press first
    capped = press_profile(PressTarget(0.0, 0.0, depth=1.6e-3, force=0.2, speed=0.01), 0.04, variability=person,
                           depth_for_force=soft, **kw)
    assert _bottom_depth(capped) == pytest.approx(soft(0.2))


@pytest.mark.parametrize("field, value", [("push_force", -1.0), ("push_force", float("nan")),
                                          ("push_depth_scale", 0.9), ("push_stiffness", -1.0),
                                          ("push_stiffness", float("inf"))])
def test_bad_push_settings_are_refused(field, value):
    with pytest.raises(ValidationError, match=f"Variability.{field}"):
        replace(ROBOT, **{field: value})


def test_running_peak_equals_the_frame_by_frame_recursion():
    rng = np.random.default_rng(3)
    for n in (1, 2, 5, 64, 257):
        p = rng.uniform(0.0, 5e4, (n, 4, 4))
        loaded = rng.random((n, 4, 4)) < 0.85
        p = np.where(loaded, p, 0.0)
        top, expected = np.zeros((4, 4)), np.empty_like(p)
        for k in range(n):
            top = np.where(loaded[k], np.maximum(top, p[k]), 0.0)
            expected[k] = top
        assert np.array_equal(_running_peak(p, loaded), expected)
