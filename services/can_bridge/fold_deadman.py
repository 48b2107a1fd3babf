"""A fold's deadman: the bridge drives a fold by itself, so it must know when to give up.

A fold (``folding_in`` / ``folding_out``) needs no velocity command: the bridge sends the
fold frame at every clean sync until the arm reports completion. Without a deadman, a
fold goes on when the process that asked for it (the sequencer, on the base computer),
the link to it, or the controller is gone. A fold requested with
``ArmCommand.heartbeat_timeout`` > 0 gets the deadman of trajectory goals
(docs/architecture.md, Freshness and safety rules), on two witnesses:

- the supervisor: at every joint state, the newest ``Heartbeat`` (the sequencer's echo of
  each joint state it receives) must echo a state no older than ``heartbeat_timeout``
  (before any echo: the fold's first joint state), judged on the joint states' stamps so
  a replay judges the same. Beyond it the fold stops. A late joint state (the arm's side
  starved: more than a cycle after the one before it) is judged as if it had come one
  cycle after it: no echo of it can exist yet (the controller's deadman does the same);
  a joint state more than ``fold_missed_cycles_to_stop`` cycles after the one before it
  (the bridge held up, a SIGSTOP) stops the fold, as the controller's gap rule aborts
  its goals.
- the arm computer itself: at every clean sync, the cycle must have given a joint state
  (a bridge woken from SIGSTOP has none: its backlog is not a joint state) and the
  controller must have answered it (its command fresh by the bridge's rule, whatever it
  says: during a fold it is zeros). Otherwise the sync is answered with zeros (the arm
  pauses); ``fold_missed_cycles_to_stop`` such syncs in a row stop the fold.

A stopped fold is phase ``stopped`` (0x370 at every sync until ``clear``): nothing
resumes by itself.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from manus.deadman import RecentStates, echo_too_old, judged_at
from manus.protocol import CYCLE_S

NS = 1_000_000_000
CYCLE_NS = round(CYCLE_S * NS)


@dataclass
class FoldDeadman:
    """The deadman of one fold.

    Attributes:
        heartbeat_timeout_s: the oldest echo allowed [s] (> 0).
        missed_to_stop: syncs in a row without a live arm computer that stop the fold.
        since_ns: stamp of the fold's first joint state [ns] (None before it).
        missed: such syncs in a row so far.
        last_ns: stamp of the joint state before [ns] (None before the first).
        recent: the newest joint states' stamps (each echo gets a full cycle).
    """

    heartbeat_timeout_s: float
    missed_to_stop: int
    since_ns: int | None = None
    missed: int = 0
    last_ns: int | None = None
    recent: RecentStates = field(default_factory=lambda: RecentStates(CYCLE_NS))

    def on_joint_state(self, stamp_ns: int, seq: int, echo_ns: int | None) -> str | None:
        """A joint state the bridge published (``echo_ns``: the stamp the newest heartbeat
        echoes, None: none yet): why the fold must stop (None: it goes on)."""
        if self.since_ns is None:
            self.since_ns = stamp_ns
        last, self.last_ns = self.last_ns, stamp_ns
        self.recent.add(stamp_ns)
        if last is not None and stamp_ns - last > self.missed_to_stop * CYCLE_NS:
            return (  # a bridge held up (SIGSTOP)
                f"no joint state for {(stamp_ns - last) / 1e6:.0f} ms before seq {seq} "
                f"(more than {self.missed_to_stop} cycles: the arm's side was held up)"
            )
        judged = judged_at(stamp_ns, last, CYCLE_NS)
        return echo_too_old(
            judged, seq, self.since_ns, echo_ns, self.heartbeat_timeout_s, self.recent
        )

    def on_sync(self, state_this_cycle: bool, controller_fresh: bool) -> tuple[bool, str | None]:
        """A clean sync: (send the fold frame, why the fold must stop or None).

        Args:
            state_this_cycle: the cycle the sync ends gave a joint state.
            controller_fresh: the controller's newest command answers the newest joint
                state (the bridge's freshness rule).
        """
        if state_this_cycle and controller_fresh:
            self.missed = 0
            return True, None
        self.missed += 1
        if self.missed < self.missed_to_stop:
            return False, None
        what = (
            "no joint state in the cycle (the bridge was held up: its input sat in a buffer)"
            if not state_this_cycle
            else "no command from the controller answering the newest joint state (is the "
            "controller running?)"
        )
        return False, f"{what}, {self.missed} cycles in a row"
