"""The invariants, judged from what the soak watched (pure functions, no clock).

Motion is judged on the simulator's truth, one sample per 60 ms cycle on the
simulator's own clock (its truth log, which a router restart does not interrupt): the
interval between two samples is *quiet* when no joint moved more than :data:`JOINT_TOL`
and the gripper not more than :data:`GRIPPER_TOL` (the drives' 20 ms lag leaves a few
hundredths of a degree after a stop).

- The arm stops: the first quiet interval after the fault starts at most
  :data:`STOP_LIMIT_NS` after it: two cycles, plus one cycle because the truth samples
  the arm once per cycle (the arm was at rest somewhere in the interval before). A
  fault the arm's side can only learn from the heartbeat deadman (the sequencer hung:
  a hang keeps its liveliness token) gets the cycles that deadman waits on top
  (:func:`stop_limit_ns`): the arm stops within two cycles of the deadman's expiry.
- Nothing resumes by itself: after that, every interval up to the recovery is quiet;
  the recovery moves no joint more than :data:`RECOVERY_TOL`; and every interval from
  the stack being ready again to the next task is quiet. A fault kind whose task may go
  on (a transient CAN fault costs a short stop, not the task) is exempt from the last two.
- One final event per task, its reason naming the fault.
- The recording is complete: every sample the soak's node received while a recorder
  was alive (its process running, its token on the bus: a router restart takes it off)
  is in that recorder's file (or the file recovered after a kill).
"""

from __future__ import annotations

import itertools
from collections import Counter
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from manus.deadman import late_states
from schemas.sequencing import TaskEvent
from schemas.state import SimTruth
from services.simulator.truth_log import TruthLine

CYCLE_NS = 60_000_000
STOP_LIMIT_NS = 3 * CYCLE_NS
"""Latest start of the first quiet interval after a fault [ns] (see the module docstring)."""


def stop_limit_ns(deadman_timeout_s: float | None = None) -> int:
    """The latest start of the first quiet interval after a fault [ns].

    :data:`STOP_LIMIT_NS` for a fault the arm's side sees at once (at the first joint
    state after it). One it can only learn from the heartbeat deadman of
    ``deadman_timeout_s`` [s] (a hung sender) is seen later: the deadman stops at the
    first joint state whose newest echo is older than the timeout. The echo of a state
    cannot come before the state, so a sender that hangs just after echoing one state
    is caught :func:`manus.deadman.late_states` states after the one at which a fault
    seen at once would be (0.1 s: one, 0.15 s: two), and the limit grows by as many cycles.
    """
    if deadman_timeout_s is None:
        return STOP_LIMIT_NS
    return STOP_LIMIT_NS + late_states(deadman_timeout_s, CYCLE_NS) * CYCLE_NS


JOINT_TOL = float(np.radians(0.05))
"""Largest joint motion of a quiet interval [rad]."""
GRIPPER_TOL = 1e-4
"""Largest gripper motion of a quiet interval [m]."""
RECOVERY_TOL = float(np.radians(0.35))
"""Largest joint motion during a recovery [rad]: a bridge that starts again pulses motors
4-6 by one count each way (``initialising``), about 0.3 deg."""
FINAL_EVENTS = ("succeeded", "failed", "cancelled")


def from_truth(truth: SimTruth) -> TruthLine:
    """A truth message as a truth-log line."""
    return TruthLine(truth.stamp_ns, truth.seq, tuple(truth.q_true), truth.gripper)


def _judged(truth: Sequence[TruthLine]) -> Iterator[tuple[TruthLine, TruthLine]]:
    """Successive samples one cycle apart (a gap is neither quiet nor moving)."""
    for a, b in itertools.pairwise(truth):
        if b.stamp_ns - a.stamp_ns <= CYCLE_NS * 3 // 2:
            yield a, b


def quiet(a: TruthLine, b: TruthLine) -> bool:
    """No joint moved more than :data:`JOINT_TOL` from ``a`` to ``b``, nor the gripper."""
    step = np.max(np.abs(np.asarray(b.q) - np.asarray(a.q)))
    return bool(step <= JOINT_TOL and abs(b.gripper - a.gripper) <= GRIPPER_TOL)


@dataclass(frozen=True)
class Stop:
    """How the arm stopped after a fault (simulator clock, ns).

    Attributes:
        stop_ns: start of the first quiet interval after the fault (None: it never
            stopped before ``end_ns``).
        resumed_ns: start of the first moving interval after the stop and before
            ``until_ns`` (None: it stayed at rest).
    """

    stop_ns: int | None
    resumed_ns: int | None


def stop_after(truth: Sequence[TruthLine], fault_ns: int, until_ns: int, end_ns: int) -> Stop:
    """When the arm came to rest after ``fault_ns``, and whether it moved again before
    ``until_ns`` (the recovery); looks for the stop up to ``end_ns``."""
    stop: int | None = None
    for a, b in _judged(truth):
        if a.stamp_ns < fault_ns or b.stamp_ns > end_ns:
            continue
        if stop is None:
            if quiet(a, b):
                stop = a.stamp_ns
        elif b.stamp_ns <= until_ns and not quiet(a, b):
            return Stop(stop, a.stamp_ns)
    return Stop(stop, None)


def first_motion(truth: Sequence[TruthLine], start_ns: int, end_ns: int) -> int | None:
    """Start of the first moving interval inside [start_ns, end_ns] (None: at rest)."""
    for a, b in _judged(truth):
        if a.stamp_ns >= start_ns and b.stamp_ns <= end_ns and not quiet(a, b):
            return a.stamp_ns
    return None


def largest_motion(truth: Sequence[TruthLine], start_ns: int, end_ns: int) -> float:
    """Largest joint displacement [rad] from the pose at ``start_ns`` during
    [start_ns, end_ns] (0: no samples)."""
    inside = [np.asarray(t.q) for t in truth if start_ns <= t.stamp_ns <= end_ns]
    if not inside:
        return 0.0
    return float(max(np.max(np.abs(q - inside[0])) for q in inside))


def final_events(events: Iterable[TaskEvent]) -> list[TaskEvent]:
    """The task's final events (succeeded, failed, cancelled)."""
    return [e for e in events if e.event in FINAL_EVENTS]


def names_fault(reason: str, words: Sequence[str]) -> bool:
    """The reason contains one of ``words`` (case-insensitive); any reason if none."""
    text = reason.lower()
    return not words or any(w in text for w in words)


@dataclass(frozen=True)
class Completeness:
    """The recording against what the soak's node received.

    Attributes:
        expected: samples received while a recorder was alive.
        lost: of those, samples in no recording.
        lost_by_key: key suffix -> lost count.
    """

    expected: int
    lost: int
    lost_by_key: dict[str, int]


def completeness(
    samples: Iterable[tuple[str, bytes, int]],
    windows: Sequence[tuple[int, int]],
    recorded: set[tuple[str, bytes]],
    prefix: str,
) -> Completeness:
    """Compare ``samples`` (key, payload hash, receive time [ns]) received inside one of
    the ``windows`` ([start, end] ns, a recorder alive) with the ``recorded`` (key, hash)."""
    expected = 0
    lost: Counter[str] = Counter()
    for key, h, t in samples:
        if not any(start <= t <= end for start, end in windows):
            continue
        expected += 1
        if (key, h) not in recorded:
            lost[key.removeprefix(prefix + "/")] += 1
    return Completeness(expected, sum(lost.values()), dict(sorted(lost.items())))


def token_gaps(changes: Iterable[tuple[int, bool]]) -> list[tuple[int, int]]:
    """[vanished, back] [ns] of one liveliness token from its changes (time, up) in the
    order seen; a token still gone at the end is gone until 2**63 - 1."""
    gaps, down = [], None
    for t, up in changes:
        if not up and down is None:
            down = t
        elif up and down is not None:
            gaps.append((down, t))
            down = None
    if down is not None:
        gaps.append((down, 2**63 - 1))
    return gaps


def seq_gaps(
    records: Iterable[tuple[str, int, int]], windows: Sequence[tuple[int, int]]
) -> dict[str, int]:
    """Messages numbered by their publisher but absent from a recording: per key, the
    missing ``seq`` numbers between two recorded neighbours that were both received
    inside the same window (a recorder alive). A smaller ``seq`` starts a new publisher
    life (a restarted service).

    Args:
        records: (key, seq, receive time [ns]) in the recording's order.
        windows: [start, end] [ns] of each recorder life.
    """
    last: dict[str, tuple[int, int]] = {}
    missing: Counter[str] = Counter()

    def window(t: int) -> int:
        return next((i for i, (a, b) in enumerate(windows) if a <= t <= b), -1)

    for key, seq, t in records:
        before = last.get(key)
        last[key] = (seq, t)
        if before is None or seq <= before[0]:
            continue
        w = window(t)
        if seq > before[0] + 1 and w >= 0 and w == window(before[1]):
            missing[key] += seq - before[0] - 1
    return dict(sorted(missing.items()))
