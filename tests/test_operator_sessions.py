"""The operator actuator takes its presses from palpate's own session files: a Tekscan export and a Liberty
recording of a person's presses, merged by ``palpate import session``, explore the object as per-press recordings
do; the halves of a session before they are merged are refused with the command that merges them."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
import rig_session as rs
from test_actuators import OPERATOR, _scenario

from palpate.core.cli import main
from palpate.core.errors import ValidationError
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.session.operator_sessions import SessionFolder
from palpate.core.session.run import run_scenario
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Scene
from palpate.core.world.workspace import map_geometries
from palpate.sim.source import SimSource

GAP = 2.0  # s between the person's presses
# test_actuators' slab widened: its 10 mm width is narrower than a 5 mm press's ~12 mm contact, whose weak signal at
# the corner cell flickers past the pad's threshold; here both pressed cells lie 15 mm inside the sides
WIDE = (OPERATOR.replace("size_mm = [30.0, 10.0, 40.0]", "size_mm = [50.0, 30.0, 40.0]")
        .replace("position_mm = [15.0, 5.0]", "position_mm = [25.0, 15.0]")
        .replace("regions = [[1, 1], [3, 1]]", "regions = [[2, 2], [4, 2]]")
        .replace("center_mm = [25.0, 5.0]", "center_mm = [35.0, 15.0]")
        .replace("size_mm = [10.0, 10.0]", "size_mm = [10.0, 30.0]"))


def _session(scenario, folder: Path, offset: float = 3.2) -> list:
    """The person presses each region once; the pad and the tracker record everything on their own clocks."""
    entry = scenario.objects[0]
    geom = map_geometries(scenario)[entry.spec.name]
    source = SimSource(Scene((entry.spec,), scenario.fingertip, scenario.taxels, scenario.pose),
                       fidelity="analytic", seed=7, variability="human")
    period = 1.0 / scenario.taxels.rate
    frames, pose_t, pose_p, pose_q, t0 = {}, [], [], [], 1.0
    for c, r in entry.regions:
        x = geom.origin[0] + (c - 0.5) * geom.cell_size
        y = geom.origin[1] + (r - 0.5) * geom.cell_size
        rec = source.press(PressTarget(x, y, depth=0.005, force=10.0))
        for f in rec.frames:
            frames[round((f.t + t0) / period)] = f.counts
        pose_t.append(np.array([p.t for p in rec.poses]) + t0)
        pose_p.append(np.array([p.position for p in rec.poses]))
        pose_q.append(np.array([p.quaternion for p in rec.poses]))
        t0 = round((pose_t[-1][-1] + GAP) / period) * period
    counts = np.zeros((int(round(t0 / period)) + 25, 4, 4), dtype=np.uint8)
    for k, v in frames.items():
        counts[k] = v
    folder.mkdir(parents=True, exist_ok=True)
    session = rs.RigSession(None, None, None, None, None, np.arange(len(counts)) * period, counts,
                            np.concatenate(pose_t), np.concatenate(pose_p), np.concatenate(pose_q), None)
    rs.write_tekscan(folder / "pad.csv", session, period)
    rs.write_liberty(folder / "liberty.mcap", rs.liberty_times(session.pose_t, offset, 0.0), session.pose_p,
                     session.pose_q, turned=False)
    return entry.regions


def test_an_operator_run_takes_its_presses_from_an_imported_session(tmp_path, monkeypatch, capsys):
    raw = tmp_path / "raw"
    _session(_scenario(WIDE), raw)
    presses = tmp_path / "presses"
    presses.mkdir()
    assert main(["import", "session", "--taxels", str(raw / "pad.csv"), "--region", "1:5,1:5", "--poses",
                 str(raw / "liberty.mcap"), "--out", str(presses / "session.mcap")]) == 0
    assert "from 2 presses" in capsys.readouterr().out
    assert SessionFolder(presses).press(1)[0].meta["press_in_file"] == 2
    sc = _scenario(WIDE, {"kind": "operator", "recordings_dir": str(presses), "figures": False})
    monkeypatch.setattr("sys.stdin", io.StringIO("\n\n"))
    summary = run_scenario(sc, tmp_path / "out")
    (obj,) = summary["objects"]
    assert obj["presses"] == 2 and [r["cell"] for r in obj["per_press"]] == [[2, 2], [4, 2]]
    post = [r["posterior"] for r in obj["per_press"]]
    assert post[0][0] > 0.99 and post[1][1] > 0.99  # the foam reads soft, the hard column hard
    assert all(not r["rejected"] for r in obj["per_press"])


def test_the_halves_of_a_session_are_refused_with_the_command_that_merges_them(tmp_path):
    raw = tmp_path / "raw"
    _session(_scenario(OPERATOR), raw)
    half = tmp_path / "half"
    half.mkdir()
    (half / "liberty.mcap").write_bytes((raw / "liberty.mcap").read_bytes())
    with pytest.raises(ValidationError, match=r"liberty.mcap holds fingertip poses but no taxel frames.*palpate "
                                              r"import session --taxels"):
        SessionFolder(half).press(0)
    pad = tmp_path / "pad"
    pad.mkdir()
    assert main(["import", "tekscan", str(raw / "pad.csv"), "--out", str(pad / "pad.mcap")]) == 0
    with pytest.raises(ValidationError, match="holds taxel frames but no fingertip poses"):
        SessionFolder(pad).press(0)


def test_a_file_with_several_presses_counts_each_and_a_new_file_is_seen(tmp_path):
    raw = tmp_path / "raw"
    _session(_scenario(OPERATOR), raw)
    folder = tmp_path / "presses"
    folder.mkdir()
    main(["import", "session", "--taxels", str(raw / "pad.csv"), "--region", "1:5,1:5", "--poses",
          str(raw / "liberty.mcap"), "--out", str(folder / "a_session.mcap")])
    presses = SessionFolder(folder)
    first, second = presses.press(0)[0], presses.press(1)[0]
    assert presses.press(2) == (None, 2)
    assert first.frames[-1].t < second.frames[0].t and first.poses[-1].t < second.poses[0].t
    # every frame and pose of the file is in exactly one press
    with RecordingWriter(folder / "b_one_more.mcap", {"scenario": None}) as w:
        for f in first.frames:
            w.write_taxel(f)
        for p in first.poses:
            w.write_pose(p)
    assert presses.press(2)[0] is not None


@pytest.mark.parametrize("gap_frames", [9, 10])
def test_a_sample_on_the_cut_between_two_presses_belongs_to_one_press(gap_frames):
    """Two contacts whose cut (half-way between one's release and the next's onset) falls on a frame and a pose
    when the gap is an even number of frames: every sample is still in exactly one press, none lost."""
    from palpate.core.perception.streams import PoseSample, PressRecording, TaxelFrame
    from palpate.core.session.operator_sessions import split_presses

    period = 1.0 / 64.0  # binary-exact times: the cut lands exactly on a sample, as rounded export times do
    active = np.zeros(60 + gap_frames, dtype=bool)
    active[10:25] = True
    active[25 + gap_frames:50 + gap_frames] = True
    frames = [TaxelFrame(k * period, np.full((4, 4), 80 if on else 0, np.uint8), 4.84e-6)
              for k, on in enumerate(active)]
    poses = [PoseSample(k * period / 2.0, np.array([0.0, 0.0, 0.05]), np.array([1.0, 0.0, 0.0, 0.0]))
             for k in range(2 * len(active))]
    parts = split_presses(PressRecording(frames, poses, None, {}), "test")
    assert len(parts) == 2
    assert [f.t for p in parts for f in p.frames] == [f.t for f in frames]
    assert [q.t for p in parts for q in p.poses] == [q.t for q in poses]
