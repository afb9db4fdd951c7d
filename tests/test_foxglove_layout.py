"""The shipped Foxglove layout is what docs/foxglove_layout.py builds with the SDK's layout types, and it shows
topics recordings hold."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

from palpate.core.io.mcap_schemas import SCHEMAS
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


def test_the_layout_shows_topics_a_recording_holds():
    layout = json.loads((models_dir() / "foxglove_layout.json").read_text())
    topics = _topics(layout, set())
    assert {"/taxels/taxels", "/pose/pose", "/annotations", "/scene", "/map/Object_1"} <= topics
    assert all(t.startswith(("/taxels/", "/pose/", "/map/")) or t in ("/annotations", "/scene") for t in topics)
    assert {"foxglove.Grid", "foxglove.RawImage", "foxglove.Log", "foxglove.SceneUpdate"} <= set(SCHEMAS)
