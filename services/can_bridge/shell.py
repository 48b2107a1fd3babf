"""The bridge's live shell: a python-can receive loop around :class:`BridgeCore`, on Zenoh.

One thread owns the bus. It waits in ``bus.recv``, stamps each frame with its arrival
time, feeds the core and **sends the core's frames before anything else**: the reply to
a 0x37F leaves before any Zenoh call of that cycle. Only then are the core's messages
published (``state/joints`` first when a 0x360 came in). Zenoh callbacks (the wiring map
:data:`services.can_bridge.wiring.WIRING`: velocity commands, e-stop, the
``bridge/command`` queryable) and the liveliness watch (a vanished ``alive/<service>``
token: :meth:`BridgeCore.on_token_gone`) feed the core under ``node.lock``; the
loop takes the same lock only around the core call itself, never around bus or Zenoh I/O.

Times: the core works on the wall clock in ns (``time.time_ns``), the clock python-can
stamps received messages with and the one :mod:`manus.node` stamps Zenoh samples with.
A frame's own timestamp is used when it is plausible (not in the future, at most a minute
old), so frames that sat in a driver buffer look old and their syncs are not answered.

Stopping (:meth:`BridgeShell.stop`, or SIGINT/SIGTERM in ``manus bridge``): the core
answers the next sync with zeros and the one after with 0x370; if no sync comes within
``shutdown_timeout_s`` both are sent at once. Then the loop ends; the caller closes the bus.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

import can
import zenoh

from manus.canbus import from_can, recv, to_can
from manus.node import Node
from manus.protocol import FrameId
from manus.session import ZenohSettings
from schemas.state import BridgeState, JointState
from services.can_bridge.config import BridgeConfig
from services.can_bridge.core import BridgeCore, Outputs
from services.can_bridge.wiring import WIRING

log = logging.getLogger("manus.bridge")

SERVICE_NAME = "can_bridge"
"""Liveliness name (``<prefix>/alive/can_bridge``)."""
TICK_NS = 20_000_000
"""Period of the core's timeout checks [ns]."""
MAX_STAMP_AGE_NS = 60_000_000_000
"""A frame timestamp older than this is taken for another clock, not for a buffer [ns]."""
HEALTH_LOG_NS = 60_000_000_000
"""The health is logged at least this often while nothing changes [ns]."""


class BridgeShell:
    """The bridge on a CAN bus and on Zenoh.

    Args:
        bus: any python-can bus (opened by the caller, closed by the caller).
        settings: how to reach Zenoh (its prefix roots the keys).
        config: bridge settings.
        session: an open Zenoh session to share (not closed by :meth:`close`).
        clock: wall clock [ns].
        on_reply: called in the loop after each reply to a sync with (sync arrival, sent)
            [ns] (benchmarks).
        on_state: called after each joint state is published with (its stamp = 0x360
            arrival, published) [ns] (benchmarks).
    """

    def __init__(
        self,
        bus: can.BusABC,
        settings: ZenohSettings | None = None,
        config: BridgeConfig | None = None,
        *,
        session: zenoh.Session | None = None,
        clock: Callable[[], int] = time.time_ns,
        on_reply: Callable[[int, int], None] | None = None,
        on_state: Callable[[int, int], None] | None = None,
    ) -> None:
        self.bus = bus
        self.core = BridgeCore(config)
        self.clock = clock
        self.on_reply = on_reply
        self.on_state = on_state
        self.node = Node(SERVICE_NAME, settings, session=session, liveliness=False)
        self.lock = self.node.lock
        self.send_errors = 0
        self.recv_errors = 0
        """Lines the bus backend could not parse (a garbled serial line; dropped)."""
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_phase = ""
        self._last_log_ns = 0
        # Everything a callback uses exists before the first subscription is declared.
        self._publish_core = WIRING.publishers(self.node)
        WIRING.attach(self.node, self.core, self._publish, now=clock, publish=self._publish_core)
        self.node.on_bad_payload = self._on_bad_payload
        self.node.watch_liveliness(self._on_alive)  # its callback runs under the node lock
        self.node.announce()  # alive once it listens and answers

    # -- Zenoh side (the wiring map's callbacks run under node.lock) ---------------------------

    def _on_alive(self, service: str, alive: bool) -> None:
        if not alive:  # a fold whose heartbeats that service sent stops at once
            self._publish(self.core.on_token_gone(service, self.clock()))

    def _on_bad_payload(self, key: str) -> None:
        with self.lock:
            self.core.on_bad_payload()

    # -- the receive loop ---------------------------------------------------------------------

    def start(self) -> None:
        """Run the receive loop in a thread."""
        self._thread = threading.Thread(target=self.run, name="manus-bridge", daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        """Ask the loop to shut the arm down and end; wait at most ``timeout`` [s]."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)

    @property
    def thread(self) -> threading.Thread | None:
        """The receive loop's thread (None before :meth:`start`)."""
        return self._thread

    @property
    def running(self) -> bool:
        """The loop thread is alive."""
        return self._thread is not None and self._thread.is_alive()

    def run(self, shutdown_timeout_s: float = 0.3) -> None:
        """The receive loop, until :meth:`stop`; then zeros and 0x370 (see the module doc)."""
        with self.lock:
            out = self.core.start(self.clock())
        self._publish(out)
        next_tick = self.clock() + TICK_NS
        deadline: int | None = None
        while True:
            if self._stop.is_set() and deadline is None:
                now = self.clock()
                deadline = now + round(shutdown_timeout_s * 1e9)
                with self.lock:
                    out = self.core.begin_shutdown(now)
                self._publish(out)
            if deadline is not None and (self.core.finished or self.clock() >= deadline):
                break
            msg = recv(self.bus, 0.01, self._garbled)
            now = self.clock()
            if msg is not None:
                self._frame(msg, now)
            if now >= next_tick:
                next_tick = now + TICK_NS
                with self.lock:
                    out = self.core.on_tick(now)
                self._send(out, None)
                self._publish(out)
        if not self.core.finished:
            now = self.clock()
            with self.lock:
                out = self.core.force_shutdown(now)
            self._send(out, None)
            self._publish(out)
        log.info("stopped: zeros and 0x370 sent")

    def _garbled(self, exc: Exception) -> None:
        self.recv_errors += 1
        log.warning("dropped a line the CAN backend could not parse (%d so far): %r",
                    self.recv_errors, exc)  # fmt: skip

    def _frame(self, msg: can.Message, now: int) -> None:
        stamp = round(msg.timestamp * 1e9) if msg.timestamp else now
        if not now - MAX_STAMP_AGE_NS <= stamp <= now:
            stamp = now
        frame = from_can(msg, stamp)
        with self.lock:
            out = self.core.on_frame(frame, now)
        sync = frame.t_ns if frame.id == FrameId.SYNC else None
        self._send(out, sync)
        self._publish(out)

    def _send(self, out: Outputs, sync_ns: int | None) -> None:
        for frame in out.frames:
            try:
                self.bus.send(to_can(frame))
            except can.CanError as exc:
                self.send_errors += 1
                log.error("cannot send 0x%03X: %s", frame.id, exc)
                continue
            if sync_ns is not None:
                sent = self.clock()
                with self.lock:
                    self.core.on_sent(sync_ns, sent)
                if self.on_reply is not None:
                    self.on_reply(sync_ns, sent)

    def _publish(self, out: Outputs) -> None:
        self._publish_core(out)  # every message on its output (an unknown one: WiringError)
        for _, msg in out.messages:
            if self.on_state is not None and isinstance(msg, JointState):
                self.on_state(msg.stamp_ns, self.clock())
            if isinstance(msg, BridgeState):
                self._log_state(msg)

    def _log_state(self, st: BridgeState) -> None:
        """Log each change of phase or detail, and the health every ``HEALTH_LOG_NS``."""
        key = f"{st.phase}: {st.detail}"
        changed = key != self._last_phase
        if not changed and st.stamp_ns - self._last_log_ns < HEALTH_LOG_NS:
            return
        self._last_phase, self._last_log_ns = key, st.stamp_ns
        warn = changed and st.phase in ("resync", "arm_error", "estopped")
        log.log(
            logging.WARNING if warn else logging.INFO,
            "phase %s (%s); cycles %d, period %.1f ms, jitter max %.1f ms, reply latency "
            "%.2f ms (max %.2f), missed windows %d, stale commands %d, resyncs %d, dropped "
            "%d, duplicate %d, late %d, garbled %d, buffered syncs %d",
            st.phase,
            st.detail,
            st.cycles,
            st.period_ms,
            st.jitter_ms,
            st.reply_latency_ms,
            st.reply_latency_max_ms,
            st.missed_windows,
            st.stale_commands,
            st.resyncs,
            st.dropped_frames,
            st.duplicate_frames,
            st.late_frames,
            st.garbled_frames,
            st.buffered_syncs,
        )

    def close(self) -> None:
        """Stop the loop (if running) and leave Zenoh; the bus stays with its owner."""
        self.stop()
        self.node.close()

    def __enter__(self) -> BridgeShell:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
