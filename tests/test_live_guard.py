"""The live view under hostile clients: a handshake never finished keeps no process alive, a client sending
malformed frames, 10 000 unknown subscriptions and a megabyte of noise keeps no one else out, each client's
handshake, idleness, message size, rate and subscriptions are capped, and no child process inherits a listening
socket. Clients are raw sockets (for what no real client library would send) and the ``websockets`` package."""

from __future__ import annotations

import asyncio
import base64
import json
import multiprocessing as mp
import os
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("foxglove", reason="the live view needs the 'live' extra (pip install 'palpate[live]')")
websockets = pytest.importorskip("websockets", reason="the live-view test client needs websockets (the 'test' extra)")

from palpate.core.io.live import LiveServer  # noqa: E402
from palpate.core.io.live_guard import GuardLimits  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
V1 = REPO / "tests" / "data" / "recording_v1"
SUBPROTOCOL = "foxglove.sdk.v1"
#: How long a test waits for something that happens at once unless there is a bug (a hang guard, not a budget).
PATIENCE = 120.0


def _handshake(port: int) -> bytes:
    key = base64.b64encode(os.urandom(16))
    return (b"GET / HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            b"Sec-WebSocket-Key: %s\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n"
            % (port, key))


def _client_frame(opcode: int, payload: bytes) -> bytes:
    """A final frame as a client sends it (masked)."""
    n, key = len(payload), os.urandom(4)
    head = bytes([0x80 | opcode])
    if n < 126:
        head += bytes([0x80 | n])
    elif n < 1 << 16:
        head += bytes([0x80 | 126]) + struct.pack(">H", n)
    else:
        head += bytes([0x80 | 127]) + struct.pack(">Q", n)
    return head + key + bytes(b ^ key[i % 4] for i, b in enumerate(payload))


class _Raw:
    """A raw client that has finished its handshake and reads the server's frames itself."""

    def __init__(self, port: int):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=PATIENCE)
        self.sock.sendall(_handshake(port))
        self.buf = b""
        while b"\r\n\r\n" not in self.buf:
            chunk = self.sock.recv(4096)
            assert chunk, self.buf
            self.buf += chunk
        head, self.buf = self.buf.split(b"\r\n\r\n", 1)
        assert head.startswith(b"HTTP/1.1 101"), head

    def frame(self) -> tuple[int, bytes] | None:
        """The server's next frame (opcode, payload); None when the connection ends."""
        while True:
            if len(self.buf) >= 2:
                n, at = self.buf[1] & 0x7F, 2
                if n == 126 and len(self.buf) >= 4:
                    n, at = struct.unpack(">H", self.buf[2:4])[0], 4
                elif n == 127 and len(self.buf) >= 10:
                    n, at = struct.unpack(">Q", self.buf[2:10])[0], 10
                if n < 126 or at > 2:
                    if len(self.buf) >= at + n:
                        out = (self.buf[0] & 0x0F, self.buf[at:at + n])
                        self.buf = self.buf[at + n:]
                        return out
            try:
                chunk = self.sock.recv(1 << 16)
            except ConnectionResetError:
                return None
            if not chunk:
                return None
            self.buf += chunk

    def channels(self) -> dict[str, int]:
        """Topic -> channel id, from the server's first advertise."""
        while True:
            got = self.frame()
            assert got is not None
            if got[0] == 1 and json.loads(got[1])["op"] == "advertise":
                return {c["topic"]: c["id"] for c in json.loads(got[1])["channels"]}

    def until_closed(self) -> int | None:
        """Read until the server ends the connection: its close code (None: cut without one). A hang fails."""
        code = None
        while (got := self.frame()) is not None:
            if got[0] == 8 and len(got[1]) >= 2:
                code = struct.unpack(">H", got[1][:2])[0]
        return code

    def send(self, opcode: int, payload: bytes) -> None:
        self.sock.sendall(_client_frame(opcode, payload))


def _subscribe(channels, first: int = 1) -> bytes:
    return json.dumps({"op": "subscribe", "subscriptions": [{"id": first + k, "channelId": c}
                                                            for k, c in enumerate(channels)]}).encode()


async def _first_map(url: str, topic: str, timeout: float) -> dict:
    """A well-formed client: handshake, subscribe to ``topic`` once advertised, the first message on it."""
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL], max_size=None, open_timeout=timeout) as ws:
        async def run():
            while True:
                frame = await ws.recv()
                if isinstance(frame, str):
                    msg = json.loads(frame)
                    ids = [c["id"] for c in msg.get("channels", []) if c["topic"] == topic]
                    if msg["op"] == "advertise" and ids:
                        await ws.send(json.dumps({"op": "subscribe",
                                                  "subscriptions": [{"id": 1, "channelId": ids[0]}]}))
                elif frame[0] == 1:
                    return json.loads(frame[13:])
        return await asyncio.wait_for(run(), timeout)


def _replay_live(tmp_path: Path, hold: float) -> tuple[subprocess.Popen, int]:
    """``palpate replay --live 0`` in a child process whose stderr nobody reads after its first line (as a
    launcher that only wants the address would); (process, port)."""
    proc = subprocess.Popen([str(Path(sys.executable).with_name("palpate")), "replay", str(V1 / "run.mcap"),
                             "--memory", str(V1 / "memory.json"), "--out", str(tmp_path / "out"), "--no-figures",
                             "--quiet", "--live", "0", "--live-speed", "0", "--live-hold", str(hold)],
                            stderr=subprocess.PIPE, stdout=subprocess.DEVNULL)
    line = proc.stderr.readline().decode()
    assert line.startswith("live view on ws://127.0.0.1:"), line
    return proc, int(line.split()[3].rsplit(":", 1)[1])


def test_a_handshake_never_finished_does_not_keep_the_process_alive(tmp_path):
    proc, port = _replay_live(tmp_path, hold=1)
    half = socket.create_connection(("127.0.0.1", port))
    half.sendall(_handshake(port)[:40])  # and nothing more, ever
    try:
        assert proc.wait(PATIENCE) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.stderr.close()
        half.close()
    assert (tmp_path / "out" / "summary.json").is_file()


def test_a_hostile_client_keeps_no_one_else_out(tmp_path):
    proc, port = _replay_live(tmp_path, hold=PATIENCE)
    try:
        hostile = _Raw(port)
        hostile.send(1, _subscribe(range(10**6, 10**6 + 10_000)))
        try:
            hostile.sock.sendall(b"\x83\x05hello" + os.urandom(1 << 20))  # reserved opcode, unmasked; then noise
        except OSError:
            pass  # cut already
        msg = asyncio.run(_first_map(f"ws://127.0.0.1:{port}", "/map/slab", 30))
        assert msg["column_count"] > 0
        hostile.until_closed()  # the guard cut the hostile client (a hang here fails the test)
    finally:
        proc.kill()
        proc.wait()
        err = proc.stderr.read().decode(errors="replace")
        proc.stderr.close()
    assert "unknown channel" not in err  # the SDK never saw the hostile subscriptions


LIMITS = GuardLimits(handshake_s=2.0, idle_s=3.0, max_message_bytes=1024, max_messages_per_s=5,
                     max_subscriptions=4, max_clients=3)


@pytest.fixture(scope="module")
def guarded():
    with LiveServer(port=0, limits=LIMITS) as server:
        for k in range(6):
            server.publish(f"/map/m{k}", "s", b"{}", 1, b"{}")
        yield server


def test_a_slow_handshake_is_cut(guarded):
    s = socket.create_connection(("127.0.0.1", guarded.port), timeout=PATIENCE)
    s.sendall(_handshake(guarded.port)[:30])
    assert s.recv(100) == b""
    s.close()


@pytest.mark.parametrize(("send", "code"), [
    (lambda c, ids: c.send(1, b" " * 2000), 1009),
    (lambda c, ids: c.send(1, _subscribe(ids[:5])), 1008),
    (lambda c, ids: [c.send(1, _subscribe(ids[:3])), c.send(1, _subscribe(ids[3:5], first=10))], 1008),
    # all at once, so a slow host cannot spread them below the rate
    (lambda c, ids: c.sock.sendall(b"".join(_client_frame(9, b"x") for _ in range(200))), 1008),
    (lambda c, ids: c.sock.sendall(b"\x81\x05hello"), 1002),
    (lambda c, ids: c.sock.sendall(b"\xc1\x80" + b"\0" * 4), 1002),
    (lambda c, ids: None, 1001),
], ids=["message over the size cap", "subscribe over the cap", "subscriptions over the cap in two",
        "over the message rate", "unmasked frame", "reserved bit", "idle (no pong)"])
def test_a_client_over_a_cap_is_closed_with_a_reason(guarded, send, code):
    c = _Raw(guarded.port)
    ids = sorted(c.channels().values())
    assert len(ids) == 6
    send(c, ids)
    assert c.until_closed() == code


def test_unknown_channels_are_dropped_and_known_ones_reach_the_server(guarded):
    c = _Raw(guarded.port)
    known = c.channels()["/map/m0"]
    c.send(1, _subscribe([10**6, known]))
    assert guarded.wait_for_subscriber("/map/m0", PATIENCE)
    c.sock.close()


def test_clients_over_the_cap_are_turned_away():
    with LiveServer(port=0, limits=LIMITS) as server:
        held = [_Raw(server.port) for _ in range(LIMITS.max_clients)]
        extra = socket.create_connection(("127.0.0.1", server.port), timeout=PATIENCE)
        extra.sendall(_handshake(server.port))
        assert extra.recv(100) == b""
        for c in held:
            c.sock.close()


def _listening_inodes(pid: int | str = "self") -> set[str]:
    """Inodes of this process's listening TCP sockets."""
    listening = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            fields = line.split()
            if fields[3] == "0A":
                listening.add(fields[9])
    held = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            target = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:
            continue
        if target.startswith("socket:[") and target[8:-1] in listening:
            held.add(target[8:-1])
    return held


def _sleep(started) -> None:
    started.set()  # the fork hook has run by now: it runs in the child before anything else
    time.sleep(PATIENCE)


@pytest.mark.skipif(not Path("/proc/net/tcp").exists(), reason="reads /proc (Linux)")
def test_no_child_process_inherits_a_listening_socket():
    before = _listening_inodes()
    with LiveServer(port=0) as server:
        live = _listening_inodes() - before
        assert len(live) == 2  # the guard's port and the SDK's private one
        with socket.create_connection(("127.0.0.1", server.port)):
            children = [subprocess.Popen(["sleep", str(PATIENCE)], close_fds=False)]
            ctx = mp.get_context("fork")
            started = ctx.Event()
            forked = ctx.Process(target=_sleep, args=(started,), daemon=True)
            forked.start()
            try:
                assert started.wait(PATIENCE)
                for pid in (children[0].pid, forked.pid):
                    assert not _listening_inodes(pid) & live, pid
            finally:
                children[0].kill()
                children[0].wait()
                forked.kill()
                forked.join()
