"""The supervisor's deadman as the controller judges it (docs/architecture.md, Freshness
and safety rules; the rule itself is :mod:`manus.deadman`, shared with the bridge).

The sequencer echoes every joint state in a ``Heartbeat``. :class:`Supervision` keeps the
newest echo and who sent it, when the current joint state is judged, and the newest
states' stamps (each echo gets a full cycle); the core asks it, per joint state, whether
the goals with a deadman (moves and gripper goals with ``heartbeat_timeout`` > 0) must
stop, and, when a liveliness token vanishes, whether they were tied to it.
"""

from __future__ import annotations

from collections.abc import Sequence

from manus.deadman import Echo, RecentStates, echo_too_old, judged_at, tied_to
from schemas.control import Heartbeat


class Supervision:
    """The newest echo, its sender, and when each joint state is judged.

    Args:
        cycle_ns: the arm's cycle [ns].
    """

    def __init__(self, cycle_ns: int) -> None:
        self.cycle_ns = cycle_ns
        self.echo = Echo()
        """The joint state the newest heartbeat echoes, and its sender."""
        self.judged_ns = 0
        """When the newest joint state is judged [ns, bridge stamps]: its stamp, or one
        cycle after the state before it if that is sooner (:func:`manus.deadman.judged_at`)."""
        self.recent = RecentStates(cycle_ns)
        """The newest joint states' stamps: each echo gets a full cycle."""

    def on_heartbeat(self, hb: Heartbeat) -> None:
        """Remember the newest joint state a heartbeat echoes, and its sender."""
        self.echo.heard(hb.ref_stamp_ns, hb.source)

    def on_joint_state(self, stamp_ns: int, last_ns: int | None) -> None:
        """A joint state stamped ``stamp_ns`` [ns] after one stamped ``last_ns`` (None:
        the first): when it is judged."""
        self.judged_ns = judged_at(stamp_ns, last_ns, self.cycle_ns)
        self.recent.add(stamp_ns)

    def lost(self, seq: int, deadmen: Sequence[tuple[float, int]]) -> str | None:
        """Why the goals must stop at the joint state ``seq`` (None: they need not).

        Args:
            seq: the joint state's sequence number (for the message).
            deadmen: per goal with a deadman, its ``heartbeat_timeout`` [s] and the stamp
                of its first joint state [ns] (the reference until a newer echo).
        """
        for limit, since in deadmen:
            lost = echo_too_old(self.judged_ns, seq, since, self.echo.ns, limit, self.recent)
            if lost is not None:
                return f"{lost} (stopped; nothing resumes by itself)"
        return None

    def tied_to(self, service: str, since: Sequence[int | None]) -> bool:
        """The newest heartbeats came from ``service`` for a goal whose first joint state
        is stamped one of ``since`` [ns] (:func:`manus.deadman.tied_to`)."""
        return any(tied_to(service, self.echo.source, s, self.echo.ns) for s in since)
