"""Saturated taxel frames are counted from the frames themselves, in the press result, the recording and the run
summary, and a run warns past 5%."""

from __future__ import annotations

import numpy as np

from palpate.core.io.mcap_reader import read_recording
from palpate.core.perception.press import perceive_press
from palpate.core.perception.streams import PressRecording, TaxelFrame, saturated_frames
from palpate.core.session.press_log import PressLog
from palpate.core.session.report import SATURATION_WARNING, saturation, saturation_warning
from palpate.sim import simulate_press


def _frames(peaks):
    out = []
    for i, p in enumerate(peaks):
        c = np.zeros((4, 4), dtype=np.uint8)
        c[1, 1] = p
        out.append(TaxelFrame(t=0.02 * i, counts=c, sensel_area=4.84e-6))
    return out


def test_a_frame_counts_as_saturated_when_any_sensel_reaches_255():
    assert saturated_frames(_frames([0, 10, 254, 255, 255, 3])) == 2
    assert saturated_frames([]) == 0
    # frames of another shape (a malformed import) are counted one at a time, not refused here
    odd = TaxelFrame(t=1.0, counts=np.full((2, 2), 255, dtype=np.uint8), sensel_area=4.84e-6)
    assert saturated_frames([*_frames([255, 3]), odd]) == 2


def test_a_hard_deep_press_is_counted_in_its_result_the_recording_and_the_summary(tmp_path):
    # 20 MPa, 3 mm: far past the 8-bit range of the default pad gain
    rec = simulate_press(2e7, fidelity="analytic", depth=0.003)
    res = perceive_press(rec)
    expected = sum(int(f.counts.max() == 255) for f in rec.frames)
    assert expected > 0 and res.saturated_frames == expected and res.frames == len(rec.frames)
    soft = perceive_press(simulate_press(2e4, fidelity="analytic", depth=0.002))
    assert soft.saturated_frames == 0
    counted = saturation([res, soft])
    assert counted.saturated_frames == expected and counted.frames == res.frames + soft.frames
    assert counted.fraction > SATURATION_WARNING
    message = saturation_warning("Block", counted)
    assert "255" in message and "gain_counts_per_kpa" in message
    assert saturation_warning("Block", saturation([soft])) is None
    log = PressLog(tmp_path / "r.mcap", {"scenario": "t"})
    log.add(rec, {"phase": "exploration", "k": 1})
    log.close()
    back = read_recording(tmp_path / "r.mcap")
    press = [a for a in back.annotations if a.kind == "press"][0]
    assert press.data["saturated_frames"] == expected and press.data["frames"] == len(rec.frames)


def test_real_style_recordings_without_truth_or_meta_are_counted_too():
    sim = simulate_press(2e7, fidelity="analytic", depth=0.003)
    rec = PressRecording(frames=sim.frames, poses=sim.poses, truth=None, meta={})
    assert perceive_press(rec).saturated_frames == saturated_frames(sim.frames) > 0
