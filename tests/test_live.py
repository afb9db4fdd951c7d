"""The live view: a WebSocket client speaking Foxglove's protocol connects, subscribes to a map and receives the
map after every press, the same JSON as the recording holds."""

from __future__ import annotations

import asyncio
import base64
import json
import struct
import subprocess
import sys
import threading
import tomllib
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("foxglove", reason="the live view needs the 'live' extra (pip install 'palpate[live]')")
websockets = pytest.importorskip("websockets", reason="the live-view test client needs websockets (the 'test' extra)")

from palpate.core.io.live import LiveServer  # noqa: E402
from palpate.core.mapping.grids import Grid2D  # noqa: E402
from palpate.core.world.scenario_file import parse_scenario  # noqa: E402

SMALL = (Path(__file__).parent / "test_run.py").read_text().split('SMALL = """', 1)[1].split('"""', 1)[0]
SUBPROTOCOL = "foxglove.sdk.v1"


async def _collect(url: str, topic: str, want: int, timeout: float) -> list:
    """Subscribe to ``topic`` and return the first ``want`` messages on it (decoded JSON)."""
    got = []
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:
        async def subscribe(channel_id: int) -> None:
            await ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": channel_id}]}))

        async def run():
            channel_id = None
            while len(got) < want:
                frame = await ws.recv()
                if isinstance(frame, str):
                    msg = json.loads(frame)
                    if msg["op"] == "advertise":
                        ids = [c["id"] for c in msg["channels"] if c["topic"] == topic]
                        if ids:
                            channel_id = ids[0]
                            await subscribe(channel_id)
                    elif msg["op"] == "status" and msg["message"] == f"Unknown channel ID: {channel_id}":
                        # The SDK can advertise a channel created during the connection a moment before it
                        # accepts subscriptions to it: ask again.
                        await asyncio.sleep(0.05)
                        await subscribe(channel_id)
                elif frame[0] == 1:  # messageData: opcode, subscription id u32, log time u64, payload
                    sub, _ = struct.unpack_from("<IQ", frame, 1)
                    assert sub == 1
                    got.append(json.loads(frame[13:]))

        await asyncio.wait_for(run(), timeout)
    return got


def _grid_probabilities(msg: dict, shape: tuple[int, int], materials: list[str]) -> np.ndarray:
    fields = {f["name"]: f for f in msg["fields"]}
    dtype = np.dtype({"names": list(fields), "formats": ["u1" if f["type"] == 1 else "<f4" for f in fields.values()],
                      "offsets": [f["offset"] for f in fields.values()], "itemsize": msg["cell_stride"]})
    cells = np.frombuffer(base64.b64decode(msg["data"]), dtype=dtype).reshape(shape)
    return np.stack([cells[f"P_{m}"] for m in materials], axis=-1)


def _scenario():
    raw = tomllib.loads(SMALL)
    raw["outputs"] = {"render_3d": False, "haptic_material": False, "figures": False}
    return parse_scenario(raw, "small.toml")


class _GateAfterFirstMap:
    """Passes messages to the server, but holds the run after its first map until the test's client has
    subscribed to it (the channel only exists once the first map is sent): every update then reaches the client,
    however the threads are scheduled."""

    def __init__(self, server: LiveServer):
        self.server, self.opened = server, False

    def publish(self, topic, *args) -> None:
        self.server.publish(topic, *args)
        if topic == "/map/slab" and not self.opened:
            self.opened = True
            assert self.server.wait_for_subscriber(topic, 120)


def test_a_client_receives_every_map_update_of_a_run(tmp_path):
    from palpate.core.session.run import run_scenario

    with LiveServer(port=0) as server:
        result: dict = {}

        def client():
            result["maps"] = asyncio.run(_collect(server.url, "/map/slab", 4, 120))

        thread = threading.Thread(target=client)
        thread.start()
        summary = run_scenario(_scenario(), tmp_path, live=_GateAfterFirstMap(server))
        thread.join(150)
    maps = result["maps"]
    assert summary["objects"][0]["presses"] == 4 and len(maps) == 4
    grid = Grid2D.load(tmp_path / "maps" / "slab.npz")
    shape, materials = grid.probabilities.shape[:2], ["soft", "medium", "hard"]
    np.testing.assert_allclose(_grid_probabilities(maps[-1], shape, materials), grid.probabilities, rtol=1e-6)
    # one update per press, in order: the explored cells grow press by press
    explored = [int(np.sum(_grid_probabilities(m, shape, materials).std(axis=-1) > 0.05)) for m in maps]
    assert explored == sorted(explored) and explored[-1] > explored[0]


def test_a_late_client_gets_the_latest_map_at_once(tmp_path):
    from palpate.core.session.run import run_scenario

    with LiveServer(port=0) as server:
        run_scenario(_scenario(), tmp_path, live=server)  # the run is over before anyone connects
        (latest,) = asyncio.run(_collect(server.url, "/map/slab", 1, 60))
    grid = Grid2D.load(tmp_path / "maps" / "slab.npz")
    np.testing.assert_allclose(_grid_probabilities(latest, grid.probabilities.shape[:2], ["soft", "medium", "hard"]),
                               grid.probabilities, rtol=1e-6)


def test_palpate_run_live_serves_the_map(tmp_path):
    scenario = tmp_path / "small.toml"
    scenario.write_text(SMALL.replace("render_3d = false", "render_3d = false\nfigures = false"))
    palpate = Path(sys.executable).with_name("palpate")
    proc = subprocess.Popen([str(palpate), "run", str(scenario), "--out", str(tmp_path / "out"), "--quiet",
                             "--live", "0", "--live-hold", "120"], stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stderr.readline()
        assert line.startswith("live view on ws://127.0.0.1:"), line
        url = line.split()[3]
        (msg,) = asyncio.run(_collect(url, "/map/slab", 1, 120))
        assert msg["column_count"] > 0 and {f["name"] for f in msg["fields"]} >= {"red", "green", "blue", "P_hard"}
    finally:
        proc.terminate()
        proc.wait(30)
        proc.stderr.close()


def test_replay_live_serves_the_rebuilt_maps(tmp_path):
    from palpate.core.perception.memory import HapticMemory
    from palpate.core.session.replay import replay_recording

    v1 = Path(__file__).parent / "data" / "recording_v1"
    with LiveServer(port=0) as server:
        replay_recording(v1 / "run.mcap", HapticMemory.load(v1 / "memory.json"), tmp_path, figures=False,
                         live=server, live_speed=0)
        (latest,) = asyncio.run(_collect(server.url, "/map/slab", 1, 60))
    grid = Grid2D.load(tmp_path / "maps" / "slab.npz")
    np.testing.assert_allclose(_grid_probabilities(latest, grid.probabilities.shape[:2], ["soft", "medium", "hard"]),
                               grid.probabilities, rtol=1e-6)
