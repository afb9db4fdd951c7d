"""The shipped Foxglove layout is what docs/foxglove_layout.py builds with the SDK's layout types, and it shows
topics recordings hold; its plots name numeric fields of those topics' schemas."""

from __future__ import annotations

import importlib.util
import json
import re
from pathlib import Path

import numpy as np
import pytest

from palpate.core.io.mcap_schemas import SCHEMAS
from palpate.core.io.mcap_writer import RecordingWriter
from palpate.core.perception.streams import PoseSample, TaxelFrame
from palpate.core.world.resources import models_dir

pytest.importorskip("foxglove.layouts", reason="building the layout needs the 'live' extra (foxglove-sdk)")
GENERATOR = Path(__file__).resolve().parent.parent / "docs" / "foxglove_layout.py"


def _generator():
    spec = importlib.util.spec_from_file_location("foxglove_layout_doc", GENERATOR)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_shipped_layout_is_the_generators_output():
    shipped = (models_dir() / "foxglove_layout.json").read_text()
    assert shipped == _generator().layout_json(), "rerun: .venv/bin/python docs/foxglove_layout.py"


def _topics(node, found):
    if isinstance(node, dict):
        for key, value in node.items():
            if key in ("imageTopic", "topicToRender", "value") and isinstance(value, str):
                found.add(value.split(".")[0])
            if key == "topics" and isinstance(value, dict):
                found.update(value)
            _topics(value, found)
    elif isinstance(node, list):
        for v in node:
            _topics(v, found)
    return found


def _written_channels() -> dict[str, str]:
    """topic -> schema name of what the writer sends for a pad ``taxels``, a pose sensor ``pose`` and a press."""
    channels = {}

    class Sink:
        def publish(self, topic, schema_name, schema, log_time, data) -> None:
            channels[topic] = schema_name

    with RecordingWriter(None, {}, live=Sink(), pad_offset=(0.0, 0.0, -0.008)) as w:
        w.write_taxel(TaxelFrame(0.0, np.zeros((4, 4), np.uint8), 1e-5, "taxels"))
        w.write_pose(PoseSample(0.0, [0.0, 0.0, 0.05], sensor_id="pose"))
        w.write_annotation(0.0, "press", {"phase": "exploration"})
    return channels


def test_the_layout_shows_topics_a_recording_holds():
    layout = json.loads((models_dir() / "foxglove_layout.json").read_text())
    topics = _topics(layout, set())
    assert {"/taxels/taxels", "/palpate/taxels/taxels", "/pose/pose", "/annotations", "/scene",
            "/map/Object_1"} <= topics
    written = _written_channels()
    assert all(t in written or t.startswith("/map/") or t == "/scene" for t in topics)
    assert {"foxglove.Grid", "foxglove.RawImage", "foxglove.Log", "foxglove.SceneUpdate"} <= set(SCHEMAS)


def _plot_paths(node, found):
    if isinstance(node, dict):
        if node.get("panelType") == "Plot":
            found.extend(p["value"] for p in node["config"]["paths"])
        for v in node.values():
            _plot_paths(v, found)
    elif isinstance(node, list):
        for v in node:
            _plot_paths(v, found)
    return found


def test_every_plotted_path_is_a_field_of_its_channels_schema():
    layout = json.loads((models_dir() / "foxglove_layout.json").read_text())
    written = _written_channels()
    paths = _plot_paths(layout, [])
    assert len(paths) == 3
    for path in paths:
        topic, *fields = path.split(".")
        schema = SCHEMAS[written[topic]]
        for field in fields:  # e.g. counts[5] -> the array counts, then its items
            name, index = re.fullmatch(r"(\w+)(\[\d+\])?", field).groups()
            assert name in schema["properties"], (path, name)
            schema = schema["properties"][name]
            if index:
                assert schema["type"] == "array", path
                schema = schema["items"]
        assert schema["type"] in ("number", "integer"), path
