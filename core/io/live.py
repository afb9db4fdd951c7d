"""The live view: the recording's channels served over Foxglove's WebSocket protocol while a run (or a replay) goes.

Open Foxglove, "Open connection", ``ws://127.0.0.1:8765`` (the default port) and import the layout
``models/foxglove_layout.json`` (shipped in the package; see ``docs/recordings.md``) to see the fingertip, the
taxel image, the map after every press and the press log as they happen. The server is the Foxglove SDK's
(``pip install 'palpate[live]'``); messages are the same JSON as in a recording (:mod:`~palpate.core.io.mcap_schemas`).

Clients reach the SDK through a guard (:mod:`~palpate.core.io.live_guard`): the SDK listens on a private loopback
port, and the guard, on the port users connect to, times out handshakes and idle clients, caps what one client may
send and subscribe to, and drops every client at once on :meth:`LiveServer.close`, which never waits on a client.

The maps and the scene are state, not events: a client that subscribes after they were sent gets the latest one at
once, so a view opened late (or after the run) still shows the current map.
"""

from __future__ import annotations

import threading

from palpate.core.extras import missing_extra
from palpate.core.io.live_guard import GuardLimits, LiveGuard, listening_fds

DEFAULT_PORT = 8765
_STATE_TOPICS = ("/map/", "/scene", "/spots/")


class LiveServer:
    """A Foxglove WebSocket server publishing palpate's channels (a :class:`~palpate.core.io.mcap_writer.LiveSink`).

    Args:
        host: address to listen on (default: this machine only).
        port: TCP port; 0 picks a free one (see :attr:`port`).
        name: server name shown by Foxglove.
        limits: what one client may do (:class:`~palpate.core.io.live_guard.GuardLimits`; default: its defaults).

    Raises:
        MissingExtraError: the Foxglove SDK (the ``live`` extra) is not installed.
        OSError-like errors from the SDK when the port is taken.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = DEFAULT_PORT, name: str = "palpate",
                 limits: GuardLimits | None = None):
        try:
            import foxglove
        except ImportError as exc:
            raise missing_extra(exc, "the live view") from None
        self._foxglove = foxglove
        self._context = foxglove.Context()
        self._channels: dict[str, object] = {}
        self._latest: dict[str, tuple[object, bytes, int]] = {}
        self._subscribed = threading.Condition()
        self._subscribers: dict[str, int] = {}
        latest, subscribed, subscribers = self._latest, self._subscribed, self._subscribers

        class _Listener(foxglove.ServerListener):
            def on_subscribe(self, client, channel) -> None:  # a late subscriber gets the current map at once
                state = latest.get(channel.topic)
                if state is not None:
                    ch, data, log_time = state
                    ch.log(data, log_time=log_time, sink_id=client.id)
                with subscribed:
                    subscribers[channel.topic] = subscribers.get(channel.topic, 0) + 1
                    subscribed.notify_all()

            def on_unsubscribe(self, client, channel) -> None:
                with subscribed:
                    subscribers[channel.topic] = max(subscribers.get(channel.topic, 0) - 1, 0)

        # The SDK on a private loopback port, the guard on the one users connect to.
        self._server = foxglove.start_server(name=name, host="127.0.0.1", port=0, context=self._context,
                                             server_listener=_Listener())
        try:
            self._guard = LiveGuard(host, port, int(self._server.port), limits,
                                    private_fds=listening_fds(int(self._server.port)))
        except BaseException:
            _stop_soon(self._server)
            raise
        self.host = host

    @property
    def port(self) -> int:
        """The TCP port the server listens on."""
        return self._guard.port

    @property
    def url(self) -> str:
        """The address to open in Foxglove."""
        return f"ws://{self.host}:{self.port}"

    def wait_for_subscriber(self, topic: str, timeout: float) -> bool:
        """Block until a client subscribes to ``topic`` (True), or ``timeout`` s pass (False). A subscriber has
        been sent the topic's latest map or scene by the time this returns."""
        with self._subscribed:
            return self._subscribed.wait_for(lambda: self._subscribers.get(topic, 0) > 0, timeout)

    def publish(self, topic: str, schema_name: str, schema: bytes, log_time: int, data: bytes) -> None:
        """Send one JSON message on ``topic`` (a channel is advertised on first use)."""
        ch = self._channels.get(topic)
        if ch is None:
            fg = self._foxglove
            ch = fg.Channel(topic, schema=fg.Schema(name=schema_name, encoding="jsonschema", data=schema),
                            message_encoding="json", context=self._context)
            self._channels[topic] = ch
        if topic.startswith(_STATE_TOPICS):
            self._latest[topic] = (ch, data, log_time)
        ch.log(data, log_time=log_time)

    def close(self) -> None:
        """Stop serving (idempotent): every client is cut, and the SDK is given a moment to stop, never more."""
        if self._server is not None:
            self._guard.close()
            _stop_soon(self._server)
            self._server = None

    def __enter__(self) -> LiveServer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _stop_soon(server, wait: float = 2.0) -> None:
    """Stop the SDK's server, waiting ``wait`` s at most: its ``stop()`` can wait on a connection forever, and a
    daemon thread left in it does not keep the process alive."""
    t = threading.Thread(target=server.stop, name="palpate live stop", daemon=True)
    t.start()
    t.join(wait)
