"""Arrival-time effects a live bridge sees: frames late but in order (a busy sender or
receiver) are accepted; a shift of the arm's phase is followed; nothing is answered twice."""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Callable

from manus.protocol import Frame, FrameId
from manus_stack.lockstep import LockStep
from schemas.state import JointState
from tests.bridge_scenarios import MS, running

Delay = Callable[[Frame], int]
"""Extra arrival delay of one arm frame [ns]."""


class Wire:
    """Delivers the arm's frames to the bridge with chosen delays (the bridge's replies
    reach the arm 1 ms after they are sent)."""

    def __init__(self, ls: LockStep) -> None:
        self.ls = ls
        self.states: list[JointState] = []
        self.replies: list[tuple[int, Frame]] = []  # (sync arrival, reply)
        self._order = itertools.count()

    def run(self, seconds: float, delay: Delay) -> None:
        sim, bridge = self.ls.sim, self.ls.bridge
        end = sim.time_ns + round(seconds * 1e9)
        queue: list[tuple[int, int, Frame]] = []
        while True:
            t_sim = sim.next_event_ns()
            t_arr = queue[0][0] if queue else None
            if t_arr is not None and t_arr < t_sim:
                _, _, f = heapq.heappop(queue)
                out = bridge.on_frame(f.at(t_arr), t_arr)
                for reply in out.frames:
                    self.replies.append((t_arr, reply))
                    sim.receive(reply.at(t_arr + MS))
                self.states += [m for _, m in out.messages if isinstance(m, JointState)]
                continue
            if t_sim > end:
                break
            for f in sim.advance(t_sim):
                heapq.heappush(queue, (f.t_ns + delay(f), next(self._order), f))
            tick = bridge.on_tick(t_sim)
            assert not tick.frames


def _cycles(wire: Wire, start_ns: int) -> int:
    return sum(1 for js in wire.states if js.stamp_ns >= start_ns)


def test_late_but_in_order_frames_are_accepted() -> None:
    ls = running()
    wire = Wire(ls)
    t0 = ls.sim.time_ns
    # Every third cycle the 0x350 and 0x360 reach the bridge 25 and 15 ms late (still
    # before the sync), and the sync itself 12 ms late.
    late = {FrameId.STATUS: 25 * MS, FrameId.POSITION: 15 * MS, FrameId.SYNC: 12 * MS}

    def delay(f: Frame) -> int:
        return late.get(FrameId(f.id), 0) if (f.t_ns // (60 * MS)) % 3 == 0 else 0

    wire.run(2.0, delay)
    h = ls.bridge.health
    assert h.resyncs == 0 and h.late_frames == 0 and h.dropped_frames == 0
    assert ls.bridge.phase == "running"
    assert _cycles(wire, t0) >= 32  # a joint state every cycle
    assert ls.sim.counters.outside_window == 0  # replies 13 ms after the sync: in time


def test_a_phase_shift_later_and_back_earlier_is_followed() -> None:
    ls = running()
    wire = Wire(ls)
    t0 = ls.sim.time_ns
    wire.run(1.0, lambda f: 15 * MS)  # every frame 15 ms late for a while
    wire.run(1.0, lambda f: 0)  # then on time again: 15 ms earlier than the anchor knew
    h = ls.bridge.health
    assert ls.bridge.phase == "running"
    assert h.resyncs <= 1
    # Every sync of the last second was answered exactly once.
    answered = [t for t, _ in wire.replies if t > t0 + 1200 * MS]
    assert len(answered) == len(set(answered)) >= 12
    assert ls.sim.counters.extra_replies == 0


def test_a_phase_shift_earlier_from_the_start_reanchors() -> None:
    ls = LockStep()
    wire = Wire(ls)
    # The first cycles reach the bridge 15 ms late (say, a slow bus open), then on time.
    wire.run(0.5, lambda f: 15 * MS)
    wire.run(2.5, lambda f: 0)
    assert ls.bridge.phase == "running"
    answered = [t for t, _ in wire.replies]
    assert len(answered) == len(set(answered))
    assert ls.sim.counters.extra_replies == 0 and ls.sim.counters.replies_latched >= 20
