"""A session from separate devices: a Tekscan export and a Liberty recording of the same simulated presses, on
clocks 1.7 s and 50 ppm apart, in a tracker frame turned and tilted from the grid's, merged by ``palpate import
session`` and mapped: the offset found within 10 ms, every press found, c_D within 0.2 mm of the simulated run's
(the same perception on the one-clock streams of each press), each press classified as the simulated run classified
it. (The perception's c_D itself runs 0.1-0.5 mm above the simulation's true indentation on one clock too: its
first-contact height comes from the 3/2 law; that is the perception's, not the session's.)"""

from __future__ import annotations

import numpy as np
import pytest
import rig_session as rs

from palpate.core.alignment.calibration import touches_from_poses, transform_from_touches
from palpate.core.alignment.clock import ClockMap, estimate_clock_map
from palpate.core.alignment.merge import merge_session
from palpate.core.cli import main
from palpate.core.errors import ValidationError
from palpate.core.io.mcap_reader import read_recording
from palpate.core.io.recording import recording_to_press_recording
from palpate.core.perception.pipeline import PipelineConfig, presses_from_recording
from palpate.core.perception.streams import PoseSample, TaxelFrame
from palpate.core.session.replay import replay_recording

OFFSET = 1.7  # s the tracker's clock is ahead of the pad's
DRIFT_PPM = 50.0


@pytest.fixture(scope="module")
def memory():
    return rs.train_memory()


@pytest.fixture(scope="module")
def session(memory):
    return rs.simulate(memory)


@pytest.fixture(scope="module")
def files(session, tmp_path_factory):
    d = tmp_path_factory.mktemp("rig")
    rs.write_tekscan(d / "press.csv", session)
    rs.write_liberty(d / "liberty.mcap", rs.liberty_times(session.pose_t, OFFSET, DRIFT_PPM), session.pose_p,
                     session.pose_q)
    t, p, q = rs.touches(np.random.default_rng(3))
    rs.write_liberty(d / "touches.mcap", rs.liberty_times(t, 500.0, DRIFT_PPM), p, q)
    return d


@pytest.fixture(scope="module")
def imported(files):
    """``palpate import session`` with the touch calibration: (session file, what it printed)."""
    import contextlib
    import io

    out = files / "session.mcap"
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        code = main(["import", "session", "--taxels", str(files / "press.csv"), "--region", "1:5,1:5", "--poses",
                     str(files / "liberty.mcap"), "--calibration", str(files / "touches.mcap"), "--out", str(out)])
    assert code == 0
    return out, printed.getvalue()


def test_the_clock_map_is_found_within_10_ms_from_the_presses(session, imported):
    out, printed = imported
    assert "clock offset" in printed and "ms (1 sigma)" in printed and "drift" in printed
    cmap = ClockMap(**_clock(out))
    # the map puts every tracker time within 10 ms of the true time, over the whole session
    t_dev = rs.liberty_times(session.pose_t, OFFSET, DRIFT_PPM)
    err = cmap.to_taxel(t_dev) - session.pose_t
    assert np.max(np.abs(err)) < 0.010, np.max(np.abs(err))
    assert cmap.offset_std < 0.005 and cmap.presses == len(session.t_press)
    assert cmap.drift_ppm == pytest.approx(DRIFT_PPM, abs=4 * cmap.rate_std * 1e6 + 5)


def _clock(path) -> dict:
    c = read_recording(path).metadata["session"]["clock"]
    return {"offset": c["offset_s"], "rate": c["rate"], "t_ref": c["t_ref_s"], "offset_std": c["offset_std_s"],
            "rate_std": c["rate_std"], "method": c["method"], "presses": c["presses"]}


def test_every_press_is_found_with_its_depth_place_and_class(session, memory, imported):
    labels, depths, locations = rs.perceived_labels(memory, imported[0])
    assert len(labels) == len(session.t_press)
    np.testing.assert_allclose(depths, session.sim_depth, atol=2e-4)
    assert labels == session.sim_labels
    assert labels == session.materials  # and the simulation's own classification was right
    # calibrated: the presses are at their places on the grid (the pad centre is the tracked sphere's xy)
    np.testing.assert_allclose(locations, session.locations, atol=1.5e-3)


@pytest.mark.parametrize("name", ["session.mcap", "uncalibrated.mcap"])
def test_replay_maps_the_session_with_the_same_classes(session, memory, imported, uncalibrated, tmp_path, name):
    summary = replay_recording(imported[0].parent / name, memory, tmp_path / "replay", figures=False)
    rows = summary["objects"][0]["per_press"]
    assert len(rows) == len(session.t_press)
    assert [memory.materials[int(np.argmax(r["posterior"]))] for r in rows] == session.sim_labels
    np.testing.assert_allclose([r["depth_m"] for r in rows], session.sim_depth, atol=2e-4)


@pytest.fixture(scope="module")
def uncalibrated(files):
    """The same session imported without the touches: positions stay in the tilted tracker frame."""
    out = files / "uncalibrated.mcap"
    assert main(["import", "session", "--taxels", str(files / "press.csv"), "--region", "1:5,1:5", "--poses",
                 str(files / "liberty.mcap"), "--out", str(out)]) == 0
    return out


def test_without_calibration_the_press_axis_from_the_motion_keeps_c_d_right(session, memory, uncalibrated):
    out = uncalibrated
    labels, depths, _ = rs.perceived_labels(memory, out)
    np.testing.assert_allclose(depths, session.sim_depth, atol=2e-4)
    assert labels == session.sim_labels
    # measured along the tracker's z instead, the 30-degree tilt shortens every press (cos 30 deg: 0.33 mm of 2.5)
    rec = recording_to_press_recording(read_recording(out))
    fixed = presses_from_recording(rec, PipelineConfig(press_axis=(0.0, 0.0, -1.0)))
    fixed_depths = np.array([p.depth for p in fixed.presses])
    assert len(fixed_depths) == len(depths)
    assert np.all(fixed_depths < depths - 5e-5)
    assert np.mean(depths - fixed_depths) > 2e-4


def test_touches_place_the_tracker_frame_on_the_grid():
    t, p, q = rs.touches(np.random.default_rng(5))
    a, b = rs.tracker_frame()
    poses = [PoseSample(ti, pi @ a.T + b, qi) for ti, pi, qi in zip(t, p, q, strict=True)]
    transform = transform_from_touches(*touches_from_poses(poses))
    # the tracker frame's inverse, up to the grid's z = 0 at the touch height
    world = np.array([[0.05, 0.02, rs.TOP + rs.TIP_R + 0.003], [0.11, 0.05, rs.TOP + rs.TIP_R]])
    grid = transform.apply([PoseSample(float(k), w @ a.T + b) for k, w in enumerate(world)])
    np.testing.assert_allclose([g.position for g in grid], world - [0, 0, rs.TOP + rs.TIP_R], atol=3e-4)
    with pytest.raises(ValidationError, match="found 2 rests"):
        touches_from_poses(poses[: int(len(poses) * 0.55)], "half.mcap")


def test_a_given_clock_offset_is_used_as_given(session, memory, files, capsys):
    out = files / "given.mcap"
    # the true map at the session's start, drift given too
    assert main(["import", "session", "--taxels", str(files / "press.csv"), "--region", "1:5,1:5", "--poses",
                 str(files / "liberty.mcap"), "--out", str(out), "--clock-offset", str(-OFFSET),
                 "--clock-drift-ppm", str(DRIFT_PPM)]) == 0
    assert "(given)" in capsys.readouterr().out
    labels, depths, _ = rs.perceived_labels(memory, out)
    assert labels == session.sim_labels


def _periodic_presses(period: float, n: int, offset: float) -> tuple[list, list]:
    """n identical presses exactly ``period`` s apart: each 1 s down and 1 s up (5 mm, raised cosine), then a move of
    20 mm sideways to the next cell. Taxel frames at 50 Hz; the fingertip's path at 240 Hz with 0.1 mm of noise,
    ``offset`` s later on the tracker's clock."""

    def depth_fraction(t: np.ndarray) -> np.ndarray:
        u = np.mod(t, period)
        return np.where(u < 2.0, 0.5 * (1.0 - np.cos(np.pi * u)), 0.0)

    t = np.arange(0.0, n * period, 1.0 / 50.0)
    frames = [TaxelFrame(float(ti), np.full((4, 4), int(200 * max(si - 0.3, 0.0)), np.uint8), 4.84e-6)
              for ti, si in zip(t, depth_fraction(t), strict=True)]
    tp = np.arange(0.0, n * period, 1.0 / 240.0)
    u = np.mod(tp, period)
    x = 0.02 * (np.floor(tp / period) + np.clip((u - 2.0) / (period - 2.0), 0.0, 1.0))
    path = np.column_stack([x, np.zeros_like(tp), 0.05 - 0.005 * depth_fraction(tp)])
    path += np.random.default_rng(4).normal(0.0, 1e-4, path.shape)
    poses = [PoseSample(float(ti + offset), p, np.array([1.0, 0.0, 0.0, 0.0])) for ti, p in zip(tp, path, strict=True)]
    return frames, poses


def test_streams_that_do_not_overlap_or_align_ambiguously_are_refused(memory, tmp_path):
    # presses at an exact rhythm look alike one period apart: refused, until the search is bounded
    frames, poses = _periodic_presses(3.2, 8, 0.4)
    with pytest.raises(ValidationError, match="ambiguous"):
        estimate_clock_map(frames, poses)
    cmap = estimate_clock_map(frames, poses, max_offset=1.0)
    assert cmap.to_taxel(0.4 + 10.0) == pytest.approx(10.0, abs=0.01)
    # a person's rhythm is not that steady: the same search finds the one offset that pairs every press
    steady = rs.simulate(memory, seed=11, n_per_material=3, steady=1.5)
    frames = [TaxelFrame(float(t), c, 4.84e-6) for t, c in zip(steady.frames_t, steady.counts, strict=True)]
    poses = [PoseSample(float(t), p, q) for t, p, q in zip(steady.pose_t + 3.0, steady.pose_p, steady.pose_q,
                                                            strict=True)]
    cmap = estimate_clock_map(frames, poses)
    assert cmap.presses == 9 and cmap.to_taxel(3.0 + 10.0) == pytest.approx(10.0, abs=0.01)
    far = [PoseSample(p.t + 1000.0, p.position, p.quaternion) for p in poses]
    with pytest.raises(ValidationError, match="do not overlap"):
        merge_session(frames, far, ClockMap(offset=0.0))
    with pytest.raises(ValidationError, match="no finished contact"):
        estimate_clock_map([TaxelFrame(float(k) * 0.02, np.zeros((4, 4), np.uint8), 4.84e-6) for k in range(50)],
                           poses)
