"""The pose and the pad's ``pose -> taxels`` transforms are exactly Foxglove's FrameTransform and join the frame
tree."""

import json
from pathlib import Path

import numpy as np

from palpate.core.io.foxglove_messages import pad_message, pose_message, stamp
from palpate.core.io.mcap_schemas import WORLD_FRAME
from palpate.core.perception.streams import PoseSample

REFERENCE = json.loads((Path(__file__).parent / "data" / "foxglove_frame_transform_fields.json").read_text())
JSON_TYPES = {"integer": int, "number": float, "string": str}


def _shape(message) -> dict | str:
    """Field names and JSON types of a message, in the form of the reference file."""
    if isinstance(message, dict):
        return {k: _shape(v) for k, v in message.items()}
    return next(name for name, kind in JSON_TYPES.items() if type(message) is kind)


def test_pad_transform_has_exactly_foxglove_fields():
    msg = pad_message(1_500_000_000, "tip", "pad", (0.0, 0.0, -0.009))
    assert _shape(msg) == REFERENCE["foxglove.FrameTransform"]


def test_pose_transform_has_exactly_foxglove_fields():
    # the pose sample's exact time goes on palpate's own channel, not into Foxglove's message
    sample = PoseSample(t=0.1 + 0.2, position=np.array([0.1, -0.2, 0.3]), quaternion=np.array([1.0, 0.0, 0.0, 0.0]))
    assert _shape(pose_message(sample, 300_000_000, "tip")) == REFERENCE["foxglove.FrameTransform"]


def test_pose_then_pad_places_a_taxel_point_in_world():
    # A point p in a child frame lies at R p + t in its parent frame (R, t: the transform's rotation, translation).
    angle = 0.7
    sample = PoseSample(t=0.25, position=np.array([0.1, -0.2, 0.3]),
                        quaternion=np.array([np.cos(angle / 2), 0.0, 0.0, np.sin(angle / 2)]))
    ns = 250_000_000
    pose = pose_message(sample, ns, "tip")
    pad = pad_message(ns, "tip", "pad", (0.0, 0.0, -0.009))
    assert pose["parent_frame_id"] == WORLD_FRAME
    assert pad["parent_frame_id"] == pose["child_frame_id"] and pad["child_frame_id"] == "pad"
    assert pad["timestamp"] == stamp(ns)
    point_in_pad = np.array([0.002, 0.0, 0.0])
    in_pose = point_in_pad + np.array([pad["translation"][k] for k in "xyz"])
    r = pose["rotation"]
    c, s = 1 - 2 * (r["z"] ** 2), 2 * r["w"] * r["z"]  # rotation about z only
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    in_world = rot @ in_pose + np.array([pose["translation"][k] for k in "xyz"])
    expected = np.array([0.1 + 0.002 * np.cos(angle), -0.2 + 0.002 * np.sin(angle), 0.3 - 0.009])
    np.testing.assert_allclose(in_world, expected, atol=1e-12)
