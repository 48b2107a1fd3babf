"""Run a :class:`SimCore` in real time against any python-can bus, in a thread.

One loop does everything, so the core needs no lock of its own: advance the core to the
monotonic clock, send what it returns, then wait in ``bus.recv`` until the next event,
stamping each received frame with its arrival time. ``lock`` serialises run-time access
from other threads (fault switches, truth readings).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import can

from manus.canbus import from_can, to_can
from manus.protocol import Frame
from schemas.base import Message
from schemas.state import SimTruth
from services.simulator.core import SimCore, SimError

log = logging.getLogger("manus.sim")

MAX_WAIT_S = 0.05
"""Longest single wait in ``bus.recv`` [s] (bounds the reaction to :meth:`LiveSim.stop`)."""


@dataclass
class LiveStats:
    """Timing health of a live run.

    Attributes:
        frames: frames handed to the bus.
        send_errors: ``bus.send`` failures (logged, the loop goes on).
        received: frames received from the bus.
        late_max_ms: largest delay from a frame's scheduled time to its send [ms].
        late_sum_ms: sum of those delays [ms] (mean = late_sum_ms / frames).
        late_over_5ms: frames sent more than 5 ms after their scheduled time.
    """

    frames: int = 0
    send_errors: int = 0
    received: int = 0
    late_max_ms: float = 0.0
    late_sum_ms: float = 0.0
    late_over_5ms: int = 0

    @property
    def late_mean_ms(self) -> float:
        """Mean send delay [ms]."""
        return self.late_sum_ms / self.frames if self.frames else 0.0


class LiveSim:
    """The core on a real clock and a real bus.

    Args:
        core: the simulator core (sim time 0 = :meth:`start`).
        bus: any python-can bus (``virtual``, :class:`~services.simulator.slcan.SlcanPtyBus`...).
        on_snapshot: called in the loop with the truth at each cycle's snapshot instant.
        on_message: called in the loop with each bus message the core publishes (key
            suffix, message; the camera's frames, the moving target's tracker), in order.
        clock: monotonic clock [ns].
        wall_clock: the clock of the stack's stamps [ns] (:attr:`wall_t0_ns`).
    """

    def __init__(
        self,
        core: SimCore,
        bus: can.BusABC,
        *,
        on_snapshot: Callable[[SimTruth], None] | None = None,
        on_message: Callable[[str, Message], None] | None = None,
        clock: Callable[[], int] = time.monotonic_ns,
        wall_clock: Callable[[], int] = time.time_ns,
    ) -> None:
        self.core = core
        self.bus = bus
        self.on_snapshot = on_snapshot
        self.on_message = on_message
        self.clock = clock
        self.wall_clock = wall_clock
        self.wall_t0_ns = 0
        """The stack's clock at simulated time 0 [ns]: a simulated stamp ``s`` is
        ``wall_t0_ns + s`` on the stack's clock (set by :meth:`start`)."""
        self.lock = threading.Lock()
        self.stats = LiveStats()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._t0 = 0
        self._last_snapshot = -1

    def start(self) -> None:
        """Power the arm up now and run in a daemon thread."""
        if self._thread is not None:
            raise SimError("this LiveSim was already started")
        self._t0 = self.clock()
        self.wall_t0_ns = self.wall_clock()
        self._thread = threading.Thread(target=self._loop, name="manus-sim", daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the loop and wait for it (at most ``timeout`` [s]); the bus stays open."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)

    @property
    def running(self) -> bool:
        """The loop thread is alive."""
        return self._thread is not None and self._thread.is_alive()

    def sim_time_ns(self) -> int:
        """The simulated time now [ns] (0 before :meth:`start`)."""
        return self.clock() - self._t0 if self._thread is not None else 0

    def _loop(self) -> None:
        try:
            while not self._stop.is_set():
                self._step()
        except Exception:
            log.exception("simulator loop failed")
            raise

    def _step(self) -> None:
        with self.lock:
            frames = self.core.advance(self.sim_time_ns())
        for frame in frames:
            self._send(frame)
        with self.lock:
            messages = self.core.take_messages()
        for _, suffix, message in messages:
            if self.on_message is not None:
                try:
                    self.on_message(suffix, message)
                except Exception:
                    log.exception("message callback failed")
        if self.on_snapshot is not None:
            with self.lock:
                truth = self._snapshot_truth()
            if truth is not None:
                try:
                    self.on_snapshot(truth)
                except Exception:
                    log.exception("snapshot callback failed")
        with self.lock:
            wait_ns = self.core.next_event_ns() - self.sim_time_ns()
        if wait_ns <= 0:
            return
        msg = self.bus.recv(timeout=min(wait_ns / 1e9, MAX_WAIT_S))
        while msg is not None:
            self.stats.received += 1
            with self.lock:
                self.core.receive(from_can(msg, self.sim_time_ns()))
            msg = self.bus.recv(timeout=0.0)

    def _snapshot_truth(self) -> SimTruth | None:
        snap = self.core.snapshot
        if snap is None or snap.t_ns == self._last_snapshot:
            return None
        self._last_snapshot = snap.t_ns
        try:
            return self.core.truth(snap.t_ns)
        except SimError:  # the loop fell behind past the next tick
            return self.core.truth()

    def _send(self, frame: Frame) -> None:
        try:
            self.bus.send(to_can(frame))
        except can.CanError as exc:
            self.stats.send_errors += 1
            log.warning("cannot send 0x%03X: %s", frame.id, exc)
            return
        late_ms = max(0.0, (self.sim_time_ns() - frame.t_ns) / 1e6)
        self.stats.frames += 1
        self.stats.late_max_ms = max(self.stats.late_max_ms, late_ms)
        self.stats.late_sum_ms += late_ms
        self.stats.late_over_5ms += late_ms > 5.0
