"""The guardian's live loop: one thread, one CAN bus, :class:`GuardianCore` in between.

Wait at most until the waiting sync's deadline (in ``select`` on the bus's descriptor when
it has one, so that no backend's polling delays the deadline; else in ``bus.recv``), stamp
each frame with the monotonic clock as it is read, feed the core, and send the 0x370 the
core asks for at once. Nothing else happens in this thread: each action goes to
``on_action`` (a logger and a queue, never a network call), so the decision never waits
on anything but the bus.
"""

from __future__ import annotations

import select
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import can

from manus.canbus import recv
from manus.protocol import Frame
from services.guardian.core import Action, GuardianCore

MAX_WAIT_S = 0.05
"""Longest single wait in ``bus.recv`` [s] (bounds the reaction to a stop request)."""


@dataclass
class LoopStats:
    """Timing of the live loop.

    Attributes:
        reaction_ms: for each 0x370 sent, from the deadline to ``bus.send`` returning [ms].
        send_errors: failed sends.
        recv_errors: lines the bus backend could not parse (dropped: ``manus.canbus.recv``).
        cpu_ns: CPU time of the loop's thread [ns].
    """

    reaction_ms: list[float] = field(default_factory=list)
    send_errors: int = 0
    recv_errors: int = 0
    cpu_ns: int = 0


def _frame(msg: can.Message, t_ns: int) -> Frame:
    data = b"" if msg.is_remote_frame else bytes(msg.data)
    return Frame(int(msg.arbitration_id), data, bool(msg.is_remote_frame), t_ns, int(msg.dlc))


def run_loop(
    bus: can.BusABC,
    core: GuardianCore,
    stop: threading.Event,
    on_action: Callable[[Action], None],
    *,
    stats: LoopStats | None = None,
    clock: Callable[[], int] = time.monotonic_ns,
) -> LoopStats:
    """Guard the bus until ``stop`` is set; returns the loop's timing."""
    stats = stats or LoopStats()
    cpu0 = time.thread_time_ns()
    try:
        fd: int | None = bus.fileno()
    except NotImplementedError:
        fd = None

    def garbled(exc: Exception) -> None:
        stats.recv_errors += 1

    while not stop.is_set():
        due = core.next_deadline_ns()
        wait = MAX_WAIT_S if due is None else min(MAX_WAIT_S, max(0.0, (due - clock()) / 1e9))
        if fd is not None:
            select.select([fd], [], [], wait)
            msg = recv(bus, 0.0, garbled)
        else:
            msg = recv(bus, wait, garbled)
        while msg is not None:
            action = core.on_frame(_frame(msg, clock()))
            if action is not None:
                on_action(action)
            msg = recv(bus, 0.0, garbled)
        frame, action = core.due(clock())
        if frame is not None and due is not None:
            try:
                bus.send(
                    can.Message(arbitration_id=frame.id, data=b"", dlc=0, is_extended_id=False)
                )
                stats.reaction_ms.append((clock() - due) / 1e6)
            except can.CanError:
                stats.send_errors += 1
        if action is not None:
            on_action(action)
        stats.cpu_ns = time.thread_time_ns() - cpu0
    return stats
