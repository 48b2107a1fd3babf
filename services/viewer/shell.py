"""The viewer's live shell: the bus in, the Foxglove WebSocket server out.

It only reads: one subscriber on ``<prefix>/**`` and one watcher of the liveliness
tokens, no publisher, no queryable, no token of its own, so the stack cannot tell it is
there. Zenoh callbacks only put each sample in a bounded queue (``queue_size``); when it
is full the sample is dropped and counted (:attr:`ViewerShell.dropped`), so a slow viewer
never holds up a Zenoh thread, and so never the stack. One worker thread feeds the queue
to :class:`~services.viewer.core.ViewerCore` and logs what it returns on the
:class:`~services.viewer.server.FoxgloveSink`.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading

import zenoh

from manus.config import DEFAULT_ARM, ArmConfig
from manus.node import Node, now_ns
from manus.session import ZenohSettings
from schemas.liveliness import LivelinessChange
from services.viewer.config import ViewerConfig
from services.viewer.core import ViewerCore
from services.viewer.server import DEFAULT_BACKLOG, DEFAULT_HOST, DEFAULT_PORT, FoxgloveSink

log = logging.getLogger("manus.viewer")

DEFAULT_QUEUE = 4096
"""Samples waiting for the worker before new ones are dropped (about 20 s of the stack's
own traffic without CAN frames, well over a second of everything)."""

_Item = tuple[str, bytes, int] | None  # key, payload, receive time; None: describe / stop


class ViewerShell:
    """Shows one arm's bus in Foxglove.

    Args:
        settings: how to reach the bus; its prefix selects the arm.
        host: WebSocket address (loopback by default).
        port: WebSocket port (0: any free one).
        session: an open session to share (not closed by :meth:`close`).
        queue_size: samples buffered before new ones are dropped.
        backlog: messages buffered per Foxglove client.
        arm: the arm's geometry (forward kinematics, URDF).
        scene: the scene drawn until the planner publishes another (``""``:
            ``$MANUS_SCENE`` or the shipped one, as every service; ``none``; a file).

    Attributes:
        received: samples received from the bus.
        dropped: samples dropped because the queue was full.
        errors: samples whose conversion raised (logged; the worker goes on).
    """

    def __init__(
        self,
        settings: ZenohSettings,
        *,
        host: str = DEFAULT_HOST,
        port: int = DEFAULT_PORT,
        session: zenoh.Session | None = None,
        queue_size: int = DEFAULT_QUEUE,
        backlog: int = DEFAULT_BACKLOG,
        arm: ArmConfig = DEFAULT_ARM,
        scene: str = "",
    ) -> None:
        self.core = ViewerCore(ViewerConfig(prefix=settings.prefix, arm=arm, scene=scene))
        self.sink = FoxgloveSink(
            host=host,
            port=port,
            urdf=self.core.urdf,
            describe_topics=(self.core.topics.robot_description, self.core.topics.scene),
            backlog=backlog,
        )
        self.sink.on_describe = self._describe_later
        for topic, schema, encoding in self.core.channels():
            self.sink.advertise(topic, schema, encoding)
        self._queue: queue.Queue[_Item] = queue.Queue(maxsize=queue_size)
        self._describe = threading.Event()
        self._stop = threading.Event()
        self.received = 0
        self.dropped = 0
        self.errors = 0
        self._count = threading.Lock()
        self._liveliness_seq = 0
        self._thread = threading.Thread(target=self._work, name="viewer", daemon=True)
        self._thread.start()
        self._describe_later()
        # Read-only: no token, no publisher; what it sees it cannot change.
        self.node = Node("viewer", settings, session=session, liveliness=False)
        self._liveliness_key = self.node.keys.liveliness
        self.node.subscribe_raw(self.node.keys.all, self._on_sample)
        self.node.watch_tokens(self.node.keys.all, self._on_token)

    @property
    def port(self) -> int:
        """The WebSocket port."""
        return self.sink.port

    def _offer(self, item: tuple[str, bytes, int]) -> None:
        try:
            self._queue.put_nowait(item)
        except queue.Full:
            with self._count:
                self.dropped += 1

    def _on_sample(self, sample: zenoh.Sample, rx_ns: int) -> None:
        if sample.kind != zenoh.SampleKind.PUT:
            return
        with self._count:
            self.received += 1
        self._offer((str(sample.key_expr), sample.payload.to_bytes(), rx_ns))

    def _on_token(self, key: str, alive: bool, rx_ns: int) -> None:
        suffix = self.node.keys.suffix(key)
        with self._count:
            seq = self._liveliness_seq
            self._liveliness_seq += 1
        change = LivelinessChange.from_token(key, suffix, alive=alive, stamp_ns=rx_ns, seq=seq)
        self._offer((self._liveliness_key, change.encode(), rx_ns))

    def _describe_later(self) -> None:
        self._describe.set()
        with contextlib.suppress(queue.Full):  # a busy worker sees the flag anyway
            self._queue.put_nowait(None)  # wake the worker

    def _work(self) -> None:
        while not self._stop.is_set():
            try:
                item = self._queue.get(timeout=0.2)
            except queue.Empty:
                item = None
            if self._describe.is_set():
                self._describe.clear()
                for msg in self.core.describe(now_ns()):
                    self.sink.log(msg)
            if item is None:
                continue
            try:
                for msg in self.core.on_sample(*item):
                    self.sink.log(msg)
            except Exception:
                self.errors += 1
                log.exception("viewer: cannot show a sample on %s", item[0])

    def stats(self) -> dict[str, object]:
        """Counters: bus side, core, Foxglove side."""
        core = self.core.stats
        return {
            "received": self.received,
            "dropped": self.dropped,
            "errors": self.errors,
            "ignored": core.ignored,
            "bad_payloads": dict(core.bad_payloads),
            "foxglove_messages": self.sink.logged,
            "client_events": dict(self.sink.client_events),
            "client_problems": self.sink.client_problems,
            "assets_served": self.sink.assets_served,
            "assets_refused": self.sink.assets_refused,
        }

    def close(self) -> None:
        """Stop listening, stop the worker, stop the server."""
        self.node.close()
        self._stop.set()
        self._thread.join()
        self.sink.close()

    def __enter__(self) -> ViewerShell:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
