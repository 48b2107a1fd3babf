"""The Foxglove side of the viewer: the SDK's WebSocket server and its channels.

:class:`FoxgloveSink` starts ``foxglove.start_server`` (default 127.0.0.1:8765) on its own
SDK context, creates one channel per topic the first time a :class:`~services.viewer.core.
FoxMessage` names it (schema and encoding from the message) and logs each message with its
log time. It serves the URDF as an asset (``package://manus/urdf/manus.urdf``, the
``assets`` capability of the Foxglove WebSocket protocol) and sends the robot description
and the scene again whenever a client subscribes to either, so a client that connects late
still sees the arm and what is around it.

What clients send is never trusted: the SDK answers a message it cannot parse, a
subscription to an unknown channel or a client publication (this server does not offer
``clientPublish``) with a status message and drops it; the sink counts what reaches it
(:attr:`FoxgloveSink.client_events`) and what the SDK reports (:class:`ClientProblemCounter`
counts the SDK's log lines about invalid client messages). Each client has a bounded
backlog (``message_backlog_size``): a slow client loses its oldest data messages and never
holds up the caller.
"""

from __future__ import annotations

import logging
import threading
from collections import Counter
from collections.abc import Callable

import foxglove
from foxglove.websocket import (
    ChannelView,
    Client,
    ClientChannel,
    PlaybackControlRequest,
    PlaybackState,
    ServerListener,
)

from manus.errors import ManusError
from services.viewer.core import FoxMessage
from services.viewer.scene import SchemaInfo

URDF_URI = "package://manus/urdf/manus.urdf"
DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
DEFAULT_BACKLOG = 1024

log = logging.getLogger("manus.viewer")


class ViewerError(ManusError):
    """The viewer cannot serve (the port is taken, the address is wrong)."""


CLIENT_LOGGER = "foxglove.websocket.connected_client"
"""The SDK's logger for what one client does (invalid messages, unknown channels...)."""


class ClientProblemCounter(logging.Handler):
    """Counts the SDK's warnings and errors about one client's input (an invalid message,
    a subscription to an unknown channel, a refused client publication)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.count = 0

    def emit(self, record: logging.LogRecord) -> None:
        self.count += 1


_PROBLEMS = ClientProblemCounter()
_INSTALLED = threading.Lock()
_installed = False


def _install_sdk_logging() -> ClientProblemCounter:
    """Route the SDK's (Rust) log into Python logging once, with the counter attached."""
    global _installed
    with _INSTALLED:
        if not _installed:
            logging.getLogger(CLIENT_LOGGER).addHandler(_PROBLEMS)
            foxglove.set_log_level(logging.WARNING)
            _installed = True
    return _PROBLEMS


class _Listener(ServerListener):
    """Counts what clients do; asks for the robot description and the scene again on a
    subscription to either."""

    def __init__(self, sink: FoxgloveSink) -> None:
        self.sink = sink

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self.sink.client_events["subscribe"] += 1
        if channel.topic in self.sink.describe_topics and self.sink.on_describe is not None:
            self.sink.on_describe()

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        self.sink.client_events["unsubscribe"] += 1

    def on_client_advertise(self, client: Client, channel: ClientChannel) -> None:
        self.sink.client_events["client_advertise"] += 1

    def on_message_data(self, client: Client, client_channel_id: int, data: bytes) -> None:
        self.sink.client_events["client_message"] += 1

    def on_playback_control_request(
        self, playback_control_request: PlaybackControlRequest
    ) -> PlaybackState | None:
        self.sink.client_events["playback_control"] += 1
        handler = self.sink.on_playback
        return handler(playback_control_request) if handler is not None else None


class FoxgloveSink:
    """The SDK's WebSocket server with the viewer's channels.

    Args:
        host: address to listen on (loopback by default).
        port: TCP port (0: any free one; see :attr:`port`).
        urdf: the URDF text served at :data:`URDF_URI`.
        describe_topics: the topics whose messages are re-sent on each subscription to one
            of them (the robot description, the scene).
        backlog: messages buffered per client before its oldest are dropped.
        name: server name shown in the app.
        playback_range: for a recording, its first and last log time [ns]: the app then
            shows a playback bar whose requests go to :attr:`on_playback`.
    """

    def __init__(
        self,
        *,
        host: str = DEFAULT_HOST,
        port: int = DEFAULT_PORT,
        urdf: str = "",
        describe_topics: tuple[str, ...] = (),
        backlog: int = DEFAULT_BACKLOG,
        name: str = "manus",
        playback_range: tuple[int, int] | None = None,
    ) -> None:
        self.problems = _install_sdk_logging()
        self._problems_at_start = self.problems.count
        self.context = foxglove.Context()
        self.describe_topics = describe_topics
        self.on_describe: Callable[[], None] | None = None
        self.on_playback: Callable[[PlaybackControlRequest], PlaybackState | None] | None = None
        self.client_events: Counter[str] = Counter()
        self.assets_served = 0
        self.assets_refused = 0
        self._urdf = urdf.encode()
        self._channels: dict[str, foxglove.Channel] = {}
        self.logged = 0
        try:
            self.server = foxglove.start_server(
                name=name,
                host=host,
                port=port,
                context=self.context,
                server_listener=_Listener(self),
                asset_handler=self._asset,
                message_backlog_size=backlog,
                playback_time_range=playback_range,
            )
        except RuntimeError as exc:
            raise ViewerError(
                f"cannot serve Foxglove on {host}:{port}: {exc} (another manus view? "
                "choose another --port)"
            ) from exc

    @property
    def port(self) -> int:
        """The TCP port the server listens on."""
        return int(self.server.port)

    @property
    def client_problems(self) -> int:
        """Invalid client messages the SDK reported since this sink started."""
        return self.problems.count - self._problems_at_start

    def _asset(self, uri: str) -> bytes | None:
        if uri == URDF_URI:
            self.assets_served += 1
            return self._urdf
        self.assets_refused += 1
        return None

    def advertise(self, topic: str, schema: SchemaInfo, encoding: str) -> foxglove.Channel:
        """The channel of ``topic``, created (and advertised to clients) if new. Channels
        advertised before their first message let a client subscribe in time for it."""
        channel = self._channels.get(topic)
        if channel is None:
            sdk_schema = foxglove.Schema(
                name=schema.name, encoding=schema.encoding, data=schema.data
            )
            channel = self._channels[topic] = foxglove.Channel(
                topic, schema=sdk_schema, message_encoding=encoding, context=self.context
            )
        return channel

    def log(self, msg: FoxMessage) -> None:
        """Log ``msg`` on its channel (created on first use)."""
        self.advertise(msg.topic, msg.schema, msg.encoding).log(msg.data, log_time=msg.log_ns)
        self.logged += 1

    def close(self) -> None:
        """Stop the server (clients are disconnected)."""
        self.server.stop()
