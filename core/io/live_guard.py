"""A guard in front of the live view's WebSocket server: what a hostile or broken client can do stops here.

The live view's server is the Foxglove SDK's (Rust, :mod:`~palpate.core.io.live`), and palpate cannot change how
it treats its clients: it waits forever on a client that never finishes its handshake (and its ``stop()`` then
never returns), and it writes a log line to stderr for each unknown channel a client subscribes to (10 000 of
them fill a pipe nobody reads, and the server stalls for every client). So the SDK listens on a private loopback
port and users connect to this guard, which hands the SDK only well-formed clients doing what a viewer does:

- a handshake (one HTTP upgrade request of at most ``max_request_bytes``) within ``handshake_s``;
- frames that follow RFC 6455 (masked, known opcodes, no reserved bits, control frames short and whole); anything
  else closes the client (close code 1002);
- messages of at most ``max_message_bytes`` (1009) at most ``max_messages_per_s`` on average (1008);
- only ``subscribe`` and ``unsubscribe``, and only for channels the server advertised: at most
  ``max_subscriptions`` per client (1008); other requests (the server offers no capability that needs them) and
  unknown channels are dropped here, so the SDK never sees them;
- a client is pinged every ``idle_s / 3`` and closed after ``idle_s`` without a byte from it, or when it does not
  take what it is sent for ``idle_s``;
- at most ``max_clients`` at once.

Shutdown never waits on a client: every connection is cut, then the loop stops. Listening sockets are not
inheritable (Python's default); a process forked while the guard runs (the figure drawer) closes its copies of
the guard's sockets and of the SDK's listening socket at once (:func:`os.register_at_fork`), so no child keeps the
port open or a client connected.

What the guard cannot control: the SDK's own port is reachable by any local process that finds it (loopback only),
and what the SDK does with the well-formed traffic the guard passes.
"""

from __future__ import annotations

import asyncio
import json
import os
import socket
import struct
import threading
import time
import weakref
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class GuardLimits:
    """What one client may do (module docstring); times in s."""

    handshake_s: float = 5.0
    idle_s: float = 30.0
    max_request_bytes: int = 8192
    max_message_bytes: int = 65536
    max_messages_per_s: float = 50.0
    max_subscriptions: int = 256
    max_clients: int = 16


class _Violation(Exception):
    def __init__(self, code: int, reason: str):
        super().__init__(reason)
        self.code = code


_CONTROL = (8, 9, 10)
#: The payload of the guard's own pings (their pongs end here).
PING = b"palpate-guard"
_KNOWN = (0, 1, 2, *_CONTROL)


def _xor(payload: bytes, key: bytes) -> bytes:
    if not payload:
        return payload
    data = np.frombuffer(payload, dtype=np.uint8)
    mask = np.resize(np.frombuffer(key, dtype=np.uint8), data.size)
    return (data ^ mask).tobytes()


def frame(opcode: int, payload: bytes, *, masked: bool) -> bytes:
    """One final WebSocket frame (masked as a client sends, unmasked as a server does)."""
    n = len(payload)
    head = bytes([0x80 | opcode])
    bit = 0x80 if masked else 0
    if n < 126:
        head += bytes([bit | n])
    elif n < 1 << 16:
        head += bytes([bit | 126]) + struct.pack(">H", n)
    else:
        head += bytes([bit | 127]) + struct.pack(">Q", n)
    if not masked:
        return head + payload
    key = os.urandom(4)
    return head + key + _xor(payload, key)


def _close_frame(code: int, reason: str) -> bytes:
    return frame(8, struct.pack(">H", code) + reason.encode()[:120], masked=False)


async def _read_frame(reader: asyncio.StreamReader, *, masked: bool, max_len: int) -> tuple[bool, int, bytes, bytes]:
    """(fin, opcode, payload unmasked, the frame's bytes as read); _Violation for a frame breaking RFC 6455."""
    head = await reader.readexactly(2)
    fin, rsv, opcode = bool(head[0] & 0x80), head[0] & 0x70, head[0] & 0x0F
    if rsv or opcode not in _KNOWN or bool(head[1] & 0x80) != masked:
        raise _Violation(1002, "malformed frame")
    n = head[1] & 0x7F
    ext = b""
    if n == 126:
        ext = await reader.readexactly(2)
        n = struct.unpack(">H", ext)[0]
    elif n == 127:
        ext = await reader.readexactly(8)
        n = struct.unpack(">Q", ext)[0]
    if opcode in _CONTROL and (not fin or n > 125):
        raise _Violation(1002, "malformed control frame")
    if n > max_len:
        raise _Violation(1009, f"message over {max_len} bytes")
    key = await reader.readexactly(4) if masked else b""
    data = await reader.readexactly(n)
    return fin, opcode, _xor(data, key) if masked else data, head + ext + key + data


class _Client:
    """One client's relay to the SDK (client -> server checked and filtered, server -> client passed on)."""

    def __init__(self, guard: LiveGuard, reader, writer, up_reader, up_writer):
        self.guard, self.limits = guard, guard.limits
        self.reader, self.writer, self.up_reader, self.up_writer = reader, writer, up_reader, up_writer
        self.advertised: set[int] = set()
        self.subscriptions: dict[int, int] = {}  # subscription id -> channel id
        self.tokens, self.refilled = 2 * self.limits.max_messages_per_s, time.monotonic()

    async def run(self) -> None:
        tasks = [asyncio.ensure_future(c) for c in (self._from_client(), self._from_server(), self._ping())]
        try:
            done, _ = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
            for t in done:
                exc = t.exception()
                if isinstance(exc, _Violation):  # say why, for a moment at most, then the connection is cut
                    self.writer.write(_close_frame(exc.code, str(exc)))
                    try:
                        await asyncio.wait_for(self.writer.drain(), 1.0)
                    except (OSError, TimeoutError):
                        pass
        finally:
            for t in tasks:
                t.cancel()

    def _rate_ok(self) -> bool:
        now = time.monotonic()
        rate = self.limits.max_messages_per_s
        self.tokens = min(2 * rate, self.tokens + (now - self.refilled) * rate)
        self.refilled = now
        self.tokens -= 1
        return self.tokens >= 0

    async def _from_client(self) -> None:
        parts: list[bytes] = []
        first = 0
        while True:
            try:
                fin, opcode, payload, _ = await asyncio.wait_for(
                    _read_frame(self.reader, masked=True, max_len=self.limits.max_message_bytes),
                    self.limits.idle_s)
            except TimeoutError:
                raise _Violation(1001, "idle") from None
            if not self._rate_ok():
                raise _Violation(1008, "too many messages")
            if opcode == 10 and payload == PING:  # the answer to the guard's ping: the client is alive
                continue
            if opcode in _CONTROL:
                self.up_writer.write(frame(opcode, payload, masked=True))
                if opcode == 8:
                    return
                continue
            if opcode == 0 and not parts or opcode != 0 and parts:
                raise _Violation(1002, "fragments out of order")
            parts.append(payload)
            first = first or opcode
            if sum(map(len, parts)) > self.limits.max_message_bytes:
                raise _Violation(1009, f"message over {self.limits.max_message_bytes} bytes")
            if not fin:
                continue
            message, kind, parts, first = b"".join(parts), first, [], 0
            if kind == 1:
                out = self._filtered(message)
                if out is not None:
                    self.up_writer.write(frame(1, out, masked=True))
                    await self.up_writer.drain()
            # binary messages (client publishing, service calls) are for capabilities the server does not offer

    def _filtered(self, message: bytes) -> bytes | None:
        """A subscribe or unsubscribe reduced to what is known and allowed; None for anything else."""
        try:
            doc = json.loads(message)
        except ValueError:
            raise _Violation(1007, "not JSON") from None
        op = doc.get("op") if isinstance(doc, dict) else None
        cap = self.limits.max_subscriptions
        if op == "subscribe":
            subs = doc.get("subscriptions")
            if not isinstance(subs, list) or len(subs) > cap:
                raise _Violation(1008, f"a subscribe of more than {cap} channels")
            keep = []
            for s in subs:
                sid, cid = (s.get("id"), s.get("channelId")) if isinstance(s, dict) else (None, None)
                # asking again for the same channel is passed on: the SDK may refuse a channel it has just advertised
                if type(sid) is int and type(cid) is int and cid in self.advertised \
                        and self.subscriptions.get(sid, cid) == cid:
                    keep.append({"id": sid, "channelId": cid})
                    self.subscriptions[sid] = cid
            if len(self.subscriptions) > cap:
                raise _Violation(1008, f"more than {cap} subscriptions")
            return json.dumps({"op": op, "subscriptions": keep}).encode() if keep else None
        if op == "unsubscribe":
            ids = doc.get("subscriptionIds")
            if not isinstance(ids, list) or len(ids) > cap:
                raise _Violation(1008, f"an unsubscribe of more than {cap} subscriptions")
            keep = [i for i in ids if type(i) is int and self.subscriptions.pop(i, None) is not None]
            return json.dumps({"op": op, "subscriptionIds": keep}).encode() if keep else None
        return None

    async def _from_server(self) -> None:
        while True:
            fin, opcode, payload, raw = await _read_frame(self.up_reader, masked=False, max_len=1 << 40)
            if opcode == 1 and fin:
                self._learn(payload)
            self.writer.write(raw)
            try:
                await asyncio.wait_for(self.writer.drain(), self.limits.idle_s)
            except TimeoutError:
                raise _Violation(1001, "not reading") from None
            if opcode == 8:
                return

    def _learn(self, payload: bytes) -> None:
        """Channels the server advertises or withdraws (the only ones a client may subscribe to)."""
        if b"advertise" not in payload[:40]:
            return
        try:
            doc = json.loads(payload)
        except ValueError:
            return
        if doc.get("op") == "advertise":
            self.advertised.update(c["id"] for c in doc.get("channels", []) if type(c.get("id")) is int)
        else:
            self.advertised.difference_update(doc.get("channelIds", []))

    async def _ping(self) -> None:
        while True:
            await asyncio.sleep(self.limits.idle_s / 3)
            self.writer.write(frame(9, PING, masked=False))


class LiveGuard:
    """Listen on ``host:port`` and relay well-behaved clients to the server on ``127.0.0.1:upstream_port``.

    Args:
        host, port: where clients connect (port 0: a free one, see :attr:`port`).
        upstream_port: the SDK server's private loopback port.
        limits: what a client may do.
        private_fds: descriptors a forked child closes at once besides the guard's own (the SDK's listener).
    """

    def __init__(self, host: str, port: int, upstream_port: int, limits: GuardLimits | None = None,
                 private_fds: tuple[int, ...] = ()):
        self.limits = limits or GuardLimits()
        self._upstream = upstream_port
        self._sock = socket.create_server((host, port), backlog=64)  # close-on-exec, as every Python socket
        self.port = int(self._sock.getsockname()[1])
        self._private = tuple(private_fds)
        self._conns: set = set()
        self._clients = 0
        self._loop = asyncio.new_event_loop()
        self._server = None
        ready = threading.Event()
        self._thread = threading.Thread(target=self._serve, args=(ready,), name="palpate live guard", daemon=True)
        self._thread.start()
        ready.wait()
        _GUARDS.add(self)

    def _serve(self, ready: threading.Event) -> None:
        asyncio.set_event_loop(self._loop)
        self._loop.set_exception_handler(_quiet_cancel)

        async def start():
            self._server = await asyncio.start_server(self._handle, sock=self._sock,
                                                      limit=self.limits.max_request_bytes)
        self._loop.run_until_complete(start())
        ready.set()
        self._loop.run_forever()
        # every connection is cut: the handlers see the end of their streams and finish (a second at most)
        pending = asyncio.all_tasks(self._loop)
        if pending:
            self._loop.run_until_complete(asyncio.wait(pending, timeout=1.0))
        for t in asyncio.all_tasks(self._loop):
            t.cancel()
        self._loop.close()

    async def _handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self._conns.add(writer)
        self._clients += 1
        up_writer = None
        try:
            if self._clients > self.limits.max_clients:
                return
            try:
                request = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), self.limits.handshake_s)
            except (TimeoutError, asyncio.LimitOverrunError, asyncio.IncompleteReadError):
                return
            head = request.split(b"\r\n", 1)[0]
            if not head.startswith(b"GET ") or b"upgrade: websocket" not in request.lower():
                writer.write(b"HTTP/1.1 400 Bad Request\r\nConnection: close\r\nContent-Length: 0\r\n\r\n")
                return
            up_reader, up_writer = await asyncio.wait_for(
                asyncio.open_connection("127.0.0.1", self._upstream, limit=1 << 16), self.limits.handshake_s)
            self._conns.add(up_writer)
            up_writer.write(request)
            response = await asyncio.wait_for(up_reader.readuntil(b"\r\n\r\n"), self.limits.handshake_s)
            writer.write(response)
            if b" 101 " not in response.split(b"\r\n", 1)[0]:
                return
            await _Client(self, reader, writer, up_reader, up_writer).run()
        except (OSError, EOFError, TimeoutError, asyncio.IncompleteReadError, asyncio.LimitOverrunError):
            pass
        finally:
            self._clients -= 1
            for w in (writer, up_writer):
                if w is not None:
                    self._conns.discard(w)
                    _cut(w)

    def close(self) -> None:
        """Cut every connection and stop listening (idempotent; never waits on a client)."""
        if self._thread is None:
            return
        _GUARDS.discard(self)

        def stop():
            if self._server is not None:
                self._server.close()
            for w in list(self._conns):
                _cut(w)
            self._loop.stop()
        try:
            self._loop.call_soon_threadsafe(stop)
        except RuntimeError:  # the loop has already ended
            pass
        self._thread.join(timeout=2.0)
        self._thread = None
        self._sock.close()

    def _fork_child_fds(self) -> list[int]:
        fds = [self._sock.fileno(), *self._private]
        for w in list(self._conns):
            sock = w.get_extra_info("socket")
            if sock is not None:
                fds.append(sock.fileno())
        return [fd for fd in fds if fd >= 0]


def _quiet_cancel(loop: asyncio.AbstractEventLoop, context: dict) -> None:
    # a handler cancelled at shutdown is not an error worth a traceback on stderr
    if not isinstance(context.get("exception"), asyncio.CancelledError):
        loop.default_exception_handler(context)


def _cut(writer: asyncio.StreamWriter) -> None:
    """Close a connection now: shut down (so a forked child's copy of the descriptor keeps nothing open), then
    abort (nothing queued is waited for)."""
    sock = writer.get_extra_info("socket")
    try:
        if sock is not None:
            sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass
    writer.transport.abort()


def listening_fds(port: int) -> tuple[int, ...]:
    """This process's descriptors of TCP sockets listening on ``port`` (Linux; () elsewhere): the SDK's listener,
    whose descriptor palpate does not otherwise see."""
    try:
        names = os.listdir("/proc/self/fd")
    except OSError:
        return ()
    found = []
    for name in names:
        try:
            copy = os.dup(int(name))
        except OSError:
            continue
        try:
            s = socket.socket(fileno=copy)
        except OSError:  # not a socket
            os.close(copy)
            continue
        try:
            if (s.family in (socket.AF_INET, socket.AF_INET6) and s.type == socket.SOCK_STREAM
                    and s.getsockopt(socket.SOL_SOCKET, socket.SO_ACCEPTCONN) and s.getsockname()[1] == port):
                found.append(int(name))
        except OSError:
            pass
        finally:
            s.close()
    return tuple(found)


# Guards running in this process, for the fork hook: a forked child must not keep their ports or clients (a
# process-wide hook needs a process-wide list; weak, so it keeps no guard alive).
_GUARDS: weakref.WeakSet[LiveGuard] = weakref.WeakSet()


def _close_in_child() -> None:
    fds = [fd for g in list(_GUARDS) for fd in g._fork_child_fds()]
    if not fds:
        return
    # /dev/null over each descriptor: the child's socket objects stay valid (nothing else reuses the number) but
    # no longer hold the port or a connection
    null = os.open(os.devnull, os.O_RDWR | os.O_CLOEXEC)
    for fd in fds:
        try:
            os.dup2(null, fd, inheritable=False)
        except OSError:
            pass
    os.close(null)


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_close_in_child)
