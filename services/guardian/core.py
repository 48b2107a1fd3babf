"""The guardian's decision: stop the arm when a sync goes unanswered. Pure, time from inputs.

The arm repeats its last command whenever a 0x37F sync gets no reply (docs/protocol.md,
The 60 ms cycle), so a bridge that dies or hangs leaves it moving. The guardian is another
node on the same CAN bus. For every sync it sees at time t it waits for a reply from
another node (any frame with a reply id: 0x370, 0x371, 0x374, 0x375, 0x376) until
``t + deadline``; if none came, it sends 0x370 (stop) itself, inside the 20 ms window,
and does so again at every sync that stays unanswered. A sync answered in time is never
touched: the guardian sends nothing while the bridge answers. It never receives its own
frames (a CAN socket does not by default, and the simulator's bus does not echo them).

No clock: frames carry their arrival time, and :meth:`GuardianCore.due` is asked with
the current time by the loop (:mod:`services.guardian.loop`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

from manus.protocol import REPLY_IDS, REPLY_WINDOW_S, Frame, FrameId, empty_frame

WINDOW_NS = round(REPLY_WINDOW_S * 1e9)
"""The arm latches the first reply within this long after a sync [ns]."""
DEFAULT_DEADLINE_MS = 12.0
"""Default wait for the bridge's reply after a sync [ms]: margin before the window closes."""


class Action(NamedTuple):
    """Something the guardian did or saw change, for its log and report.

    Attributes:
        kind: ``stop_sent`` (a sync went unanswered: 0x370 sent), ``late`` (unanswered,
            but the window had closed when the loop noticed: nothing sent) or
            ``bridge_back`` (a sync answered by another node after stops).
        sync_ns: arrival time of the sync concerned [ns].
        t_ns: when it was decided [ns].
    """

    kind: str
    sync_ns: int
    t_ns: int


@dataclass
class GuardianCounts:
    """What the guardian has seen and done since start (plain event counts)."""

    syncs: int = 0
    answered: int = 0
    stops_sent: int = 0
    late: int = 0
    other_frames: int = 0


class GuardianCore:
    """The decision (see the module docstring).

    Args:
        deadline_ms: how long after a sync a reply may come before the guardian stops the
            arm [ms]; below the 20 ms window, leaving time for the 0x370 to arrive.

    Raises:
        ValueError: ``deadline_ms`` is not in (0, 20).
    """

    def __init__(self, deadline_ms: float = DEFAULT_DEADLINE_MS) -> None:
        if not 0.0 < deadline_ms < REPLY_WINDOW_S * 1e3:
            raise ValueError(f"deadline_ms must be in (0, 20) ms, got {deadline_ms}")
        self.deadline_ns = round(deadline_ms * 1e6)
        self.counts = GuardianCounts()
        self.engaged = False
        """The last sync went unanswered and the guardian stopped the arm."""
        self._sync_ns: int | None = None  # the sync waiting for a reply

    def on_frame(self, frame: Frame) -> Action | None:
        """A frame from the bus, stamped with its arrival time."""
        if frame.id == FrameId.SYNC and frame.remote:
            self.counts.syncs += 1
            self._sync_ns = frame.t_ns
        elif frame.id in REPLY_IDS:
            sync = self._sync_ns
            if sync is None or not 0 <= frame.t_ns - sync < WINDOW_NS:
                self.counts.other_frames += 1
                return None
            self._sync_ns = None
            self.counts.answered += 1
            if self.engaged:
                self.engaged = False
                return Action("bridge_back", sync, frame.t_ns)
        return None

    def next_deadline_ns(self) -> int | None:
        """When :meth:`due` must be asked next [ns] (None: no sync is waiting)."""
        return None if self._sync_ns is None else self._sync_ns + self.deadline_ns

    def due(self, now_ns: int) -> tuple[Frame | None, Action | None]:
        """At ``now_ns``: the 0x370 to send now if the waiting sync's deadline passed
        unanswered (None if the window has closed meanwhile), and what was decided."""
        sync = self._sync_ns
        if sync is None or now_ns < sync + self.deadline_ns:
            return None, None
        self._sync_ns = None
        if now_ns - sync >= WINDOW_NS:
            self.counts.late += 1
            return None, Action("late", sync, now_ns)
        self.engaged = True
        self.counts.stops_sent += 1
        return empty_frame(FrameId.STOP, now_ns), Action("stop_sent", sync, now_ns)
