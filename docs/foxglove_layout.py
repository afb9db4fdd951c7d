"""Writes palpate's Foxglove layout, ``models/foxglove_layout.json`` (shipped inside the package).

Run: ``.venv/bin/python docs/foxglove_layout.py`` (needs the 'live' extra: the layout is built with the Foxglove
SDK's layout types, so Foxglove reads it). ``tests/test_foxglove_layout.py`` checks the shipped file is this
script's output. What the layout shows is described in ``docs/recordings.md``.
"""

from __future__ import annotations

import json
from pathlib import Path

import foxglove.layouts as fl

OUT = Path(__file__).resolve().parent.parent / "models" / "foxglove_layout.json"
# The map topics of the shipped scenarios' objects (a recording has one /map/<object> per explored object).
MAP_OBJECTS = ("Object_1", "Object_2", "Object_3", "Block", "Strip", "recording")
TAXELS, POSE = "/taxels/taxels", "/pose/pose"
TAXEL_DATA = "/palpate/taxels/taxels"  # the frames' counts as numbers (the image view holds them as bytes)


def layout() -> fl.Layout:
    """3-D scene (objects, fingertip frame, maps coloured by P(material)) | taxel image over the taxel counts and the
    true force | the press log."""
    topics = {f"/map/{name}": fl.BaseRendererGridTopicSettings(visible=True, color_mode="rgba-fields",
                                                               show_lines=True)
              for name in MAP_OBJECTS}
    topics["/scene"] = fl.BaseRendererSceneUpdateTopicSettings(visible=True, show_outlines=True)
    three_d = fl.ThreeDeePanel(title="scene: objects, fingertip, map (red/green/blue = P(material 1/2/3))",
                               config=fl.ThreeDeeConfig(follow_tf="world", fixed_frame="world", topics=topics))
    image = fl.ImagePanel(title="taxel pad (raw counts)",
                          config=fl.ImageConfig(image_mode=fl.ImageModeConfig(image_topic=TAXELS,
                                                                              color_mode="colormap",
                                                                              color_map="turbo")))
    plot = fl.PlotPanel(title="contact: two taxels (counts) and the fingertip height (m)",
                        config=fl.PlotConfig(paths=[fl.PlotSeries(value=f"{TAXEL_DATA}.counts[5]"),
                                                    fl.PlotSeries(value=f"{TAXEL_DATA}.counts[6]"),
                                                    fl.PlotSeries(value=f"{POSE}.translation.z")]))
    log = fl.LogPanel(title="presses", config=fl.LogConfig(topic_to_render="/annotations", min_log_level=1))
    return fl.Layout(content=fl.SplitContainer(direction="row", items=[
        fl.SplitItem(proportion=2, content=three_d),
        fl.SplitItem(proportion=1, content=fl.SplitContainer(direction="column", items=[
            fl.SplitItem(content=image), fl.SplitItem(content=plot), fl.SplitItem(content=log)])),
    ]))


def layout_json() -> str:
    """The layout as the file holds it (indented, stable key order)."""
    return json.dumps(json.loads(layout().to_json()), indent=1, sort_keys=True) + "\n"


if __name__ == "__main__":
    OUT.write_text(layout_json())
    print(f"wrote {OUT}")
