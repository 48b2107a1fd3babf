"""The supervisor's deadman, judged the same wherever the arm is driven: by the controller
for moves and gripper goals, by the bridge for folds (docs/architecture.md, Freshness and
safety rules).

The supervisor (the sequencer) echoes every joint state it receives in a ``Heartbeat``.
At each joint state the newest echo must refer to a state no older than the goal's
``heartbeat_timeout``, judged on the joint states' stamps (the bridge's clock), so a
replay judges the same. Pure functions (and the few stamps :class:`RecentStates` keeps),
so both services hold the rule once. Each echo gets a full cycle: a state that came late
credits the echo before it with its lateness (:class:`RecentStates`).

A hang (SIGSTOP) keeps the sender's liveliness token; a killed sender or a cut link
drops it at once (Zenoh drops a session's tokens when its link closes). So a goal whose
heartbeats came from ``source`` also stops when the token ``alive/<source>`` vanishes
(:func:`tied_to`), without waiting for its echo to grow old.
"""

from __future__ import annotations

from collections import deque


def judged_at(stamp_ns: int, last_ns: int | None, cycle_ns: int) -> int:
    """When a joint state stamped ``stamp_ns`` is judged [ns]: its stamp, or one cycle
    after the state before it (stamped ``last_ns``; None: none) if that is sooner. No
    echo of a late state (the arm's side starved of CPU) can exist yet, and a late arm
    cycle is the gap rules' business, not the link's."""
    if last_ns is None or stamp_ns <= last_ns:
        return stamp_ns
    return min(stamp_ns, last_ns + cycle_ns)


def late_states(timeout_s: float, cycle_ns: int) -> int:
    """How many joint states after the last echoed one still pass under a deadman of
    ``timeout_s`` [s]: ``floor(timeout / cycle)`` (0.1 s: one, 0.15 s: two). A sender that
    hangs just after an echo is caught at the state after those, that many cycles later
    than a fault seen at once."""
    return round(timeout_s * 1e9) // cycle_ns


class Echo:
    """The newest heartbeat's echo: the joint state it refers to and who sent it.

    Attributes:
        ns: stamp of the joint state the newest heartbeat echoes [ns] (None: none yet).
        source: its sender (``Heartbeat.source``: its ``alive/<source>`` token).
    """

    def __init__(self) -> None:
        self.ns: int | None = None
        self.source = ""

    def heard(self, ref_stamp_ns: int, source: str) -> None:
        """A heartbeat echoing the joint state stamped ``ref_stamp_ns`` [ns]: kept if newer."""
        if self.ns is None or ref_stamp_ns > self.ns:
            self.ns, self.source = ref_stamp_ns, source


class RecentStates:
    """The stamps of the newest joint states, for the credit of :func:`echo_too_old`.

    A joint state that comes late (the arm's side held up) is followed by the next one in
    less than a cycle, so its echo has less than a cycle to come back before the next
    state is judged: an echo 40 ms late then looked like a lost supervisor, on a machine
    under load. :meth:`credit` moves the newest echo's reference forward by the lateness
    of the state after it, which gives every echo a full cycle; a supervisor that hangs
    is still caught on the same state as before wherever the states come on time.

    Args:
        cycle_ns: the arm's cycle [ns].
        keep: how many stamps to keep (8: about half a second).
    """

    def __init__(self, cycle_ns: int, keep: int = 8) -> None:
        self.cycle_ns = cycle_ns
        self._stamps: deque[int] = deque(maxlen=keep)

    def add(self, stamp_ns: int) -> None:
        """A joint state, stamped ``stamp_ns`` [ns] (newer than the last)."""
        if not self._stamps or stamp_ns > self._stamps[-1]:
            self._stamps.append(stamp_ns)

    def credit(self, ref_ns: int) -> int:
        """``ref_ns`` (the stamp of a joint state) moved forward to one cycle before the
        state that followed it, if that one came late [ns]; unchanged when the state is
        not among the newest or nothing has followed it yet."""
        stamps = self._stamps
        for k in range(len(stamps) - 1):
            if stamps[k] == ref_ns:
                return max(ref_ns, stamps[k + 1] - self.cycle_ns)
        return ref_ns


def echo_too_old(
    judged_ns: int,
    seq: int,
    since_ns: int,
    echo_ns: int | None,
    timeout_s: float,
    recent: RecentStates | None = None,
) -> str | None:
    """Why the goal must stop at the joint state ``seq`` judged at ``judged_ns`` (None: it
    need not).

    Args:
        judged_ns: :func:`judged_at` of the joint state [ns].
        seq: its sequence number (for the message).
        since_ns: stamp of the goal's first joint state [ns]: the reference until an echo
            newer than it arrives.
        echo_ns: stamp of the joint state the newest heartbeat echoes [ns] (None: none).
        timeout_s: the goal's ``heartbeat_timeout`` [s], > 0.
        recent: the newest joint states (None: no credit): the reference is credited
            with the lateness of the state after it (:class:`RecentStates`).
    """
    ref = since_ns if echo_ns is None or echo_ns < since_ns else echo_ns
    credited = ref if recent is None else recent.credit(ref)
    if judged_ns - credited <= timeout_s * 1e9:
        return None
    late = (
        ""
        if credited == ref
        else f" ({(credited - ref) / 1e6:.0f} ms of it the next joint state's lateness)"
    )
    return (
        f"lost the supervisor's heartbeat: the newest echoes joint state stamp {ref} ns, "
        f"{(judged_ns - ref) / 1e6:.0f} ms before joint state seq {seq}{late}, more than "
        f"heartbeat_timeout {timeout_s * 1000:.0f} ms"
    )


def tied_to(service: str, source: str, since_ns: int | None, echo_ns: int | None) -> bool:
    """A goal judged from the joint state stamped ``since_ns`` (None: not started) stops
    when the token ``alive/<service>`` vanishes: the newest heartbeat (sent by ``source``,
    echoing the state stamped ``echo_ns``) came from that service for this goal (it echoes
    the goal's first state or a later one). A goal whose heartbeats come from a client
    without a token, or none yet, is left to the echo's age."""
    return (
        since_ns is not None and echo_ns is not None and echo_ns >= since_ns and source == service
    )


def token_gone(service: str) -> str:
    """Why a goal tied to ``alive/<service>`` (:func:`tied_to`) stops when it vanishes."""
    return (
        f"the {service}'s liveliness token went: process died or link cut (it sent the heartbeats)"
    )
