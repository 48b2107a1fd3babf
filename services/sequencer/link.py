"""The link to the arm, as the sequencer hears it: when the joint states came last and,
when they stop, what stopped them as far as the arm computer's other messages tell.

The CAN guardian (``guardian/report``) runs on the arm computer beside the bridge: while
its reports keep coming after the joint states stopped, the link is up and the bridge is
the one that fell silent (:meth:`LinkWatch.silence_cause`).
"""

from __future__ import annotations

from schemas.guardian import GuardianReport

NS = 1_000_000_000

HEARD_AFTER_NS = 120_000_000
"""A guardian report received this long after the newest joint state was sent after the
joint states stopped, not before a cut link (two cycles: both stream at most one per
cycle) [ns]."""


class LinkWatch:
    """Receive times of the newest joint state and guardian reports [ns] (None: none yet)."""

    def __init__(self) -> None:
        self.js_rx: int | None = None  # receive time of the newest joint state [ns]
        self.guardian_rx: int | None = None  # receive time of its newest report [ns]
        self.guardian_engaged_rx: int | None = None  # ... of its newest 'engaged' one
        self.tick_ns: int | None = None  # the sequencer's own previous tick [ns]
        self.back_ns: int | None = None  # its first tick after a gap of its own [ns]

    def on_tick(self, now_ns: int, timeout_s: float) -> None:
        """The sequencer's own tick at ``now_ns``. One more than ``timeout_s`` [s] after
        the previous one means this process did not run meanwhile (suspended, or starved
        of the CPU): the joint states it did not hear then were no silence of the
        bridge's, and :meth:`silence` counts from its return. (Seen in the chaos soak: a
        sequencer frozen 1.5 s blamed the bridge on waking, before it read the
        controller's result naming the lost heartbeat.)"""
        if self.tick_ns is not None and now_ns - self.tick_ns > timeout_s * NS:
            self.back_ns = now_ns
        self.tick_ns = now_ns

    def on_joint_state(self, now_ns: int) -> None:
        """A joint state arrived at ``now_ns``."""
        self.js_rx = now_ns

    def on_guardian_report(self, report: GuardianReport, now_ns: int) -> None:
        """A guardian report arrived at ``now_ns``."""
        self.guardian_rx = now_ns
        if report.engaged:
            self.guardian_engaged_rx = now_ns

    def silence_cause(self, js_rx: int) -> str:
        """What stopped the joint states (received last at ``js_rx``), as far as the arm
        computer's other messages tell."""
        after = js_rx + HEARD_AFTER_NS
        engaged = self.guardian_engaged_rx
        if engaged is not None and engaged > after:
            return (
                "can_bridge stopped answering the arm (the guardian sends the stops in its "
                "place and reports it, so the link to the arm computer is up): can_bridge "
                "hangs or died"
            )
        heard = self.guardian_rx
        if heard is not None and heard > after:
            return (
                "can_bridge publishes none, though the arm computer is heard (the guardian "
                "reports): the bridge or its input from the arm is stuck"
            )
        return (
            "nothing is heard from the arm computer (nor from its guardian): the link to it "
            "is down; the controller stops the arm itself when it loses the supervisor's "
            "heartbeat"
        )

    def silence(self, now_ns: int, timeout_s: float) -> str:
        """Why the task fails when no joint state came for more than ``timeout_s`` [s] by
        ``now_ns`` ('' when one did, or none came yet)."""
        if self.js_rx is None:
            return ""
        since = self.js_rx if self.back_ns is None else max(self.js_rx, self.back_ns)
        silent = now_ns - since
        if silent <= timeout_s * NS:
            return ""
        return (
            f"no joint states from the arm for {silent / 1e6:.0f} ms (more than link_timeout_s "
            f"{timeout_s:g} s): {self.silence_cause(since)}"
        )
