"""A scripted PC for lock-step runs: drives a :class:`SimCore` through the raw protocol.

It does what a bridge does on the wire and nothing more: it collects the arm's frames
and, at each 0x37F sync, sends the reply a script chooses, ``latency_ns`` after the sync.
Tests and the step-response plot use it; it is no bridge (no freshness rules, no
resynchronisation).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from manus.protocol import (
    GEN_ANGLES_MEASURED,
    ZERO_JOINT_MOVE,
    Frame,
    FrameId,
    MessageClass,
    MoveCommand,
    PositionFrame,
    StatusFrame,
    decode_position,
    decode_status,
    move_frame,
)
from services.simulator.core import MS, SimCore

Answer = Callable[[Frame], Frame | None]
"""Chooses the reply to one sync frame (None: stay silent); times are set by the caller."""


@dataclass(frozen=True)
class Cycle:
    """One cycle's report as the PC received it.

    Attributes:
        t_ns: send time of the 0x350 frame (the snapshot time) [ns].
        status: decoded 0x350.
        position: decoded 0x360 of the same cycle, None if it did not arrive (well-formed).
    """

    t_ns: int
    status: StatusFrame
    position: PositionFrame | None

    @property
    def fields(self) -> tuple[int, ...]:
        """The six position fields (joints 1..6 in joint mode) [0.1 deg]."""
        pos = self.position.fields if self.position else (0, 0, 0)
        return self.status.fields + pos


@dataclass
class ScriptedPc:
    """The PC side of a lock-step run.

    Attributes:
        core: the simulator.
        latency_ns: time from a sync to the reply's arrival [ns].
        frames: every frame the arm sent, in order.
        cycles: every well-formed 0x350 (with its 0x360 when it came), in order.
    """

    core: SimCore
    latency_ns: int = 1 * MS
    frames: list[Frame] = field(default_factory=list)
    cycles: list[Cycle] = field(default_factory=list)

    def run(self, until_ns: int, answer: Answer | Frame | None = None) -> list[Frame]:
        """Run to ``until_ns``, answering every sync with ``answer`` (a frame or a script).

        Returns:
            the frames the arm sent meanwhile.
        """
        sent: list[Frame] = []
        while True:
            t = self.core.next_event_ns()
            if t > until_ns:
                sent += self._take(self.core.advance(until_ns), None)
                return sent
            sent += self._take(self.core.advance(t), answer)

    def run_cycles(self, n: int, answer: Answer | Frame | None = None) -> list[Frame]:
        """Run ``n`` whole cycles (60 ms each) from now."""
        return self.run(self.core.time_ns + n * 60 * MS, answer)

    def wait_ready(self, answer: Answer | Frame | None = None, limit_ns: int = 5000 * MS) -> None:
        """Run until the arm reports "absolute angles measured".

        Raises:
            TimeoutError: it did not within ``limit_ns`` of simulated time.
        """
        while self.core.time_ns < limit_ns:
            self.run_cycles(1, answer)
            if any(
                c.status.msg_class == MessageClass.GENERAL
                and c.status.msg_code == GEN_ANGLES_MEASURED
                for c in self.cycles
            ):
                return
        raise TimeoutError(f"no 'absolute angles measured' within {limit_ns / 1e6:.0f} ms")

    def enter_joint_mode(self) -> None:
        """Wait for "absolute angles measured", then answer two syncs with a zero 0x374.

        Afterwards the arm is in joint mode with valid positions, at a sync instant.
        """
        self.wait_ready()
        self.run_cycles(2, move_frame(ZERO_JOINT_MOVE))

    def last_sync_ns(self) -> int:
        """Send time of the newest sync frame received [ns].

        Raises:
            LookupError: no sync has been received.
        """
        for f in reversed(self.frames):
            if f.id == FrameId.SYNC and f.remote:
                return f.t_ns
        raise LookupError("no sync frame received yet")

    def _take(self, frames: list[Frame], answer: Answer | Frame | None) -> list[Frame]:
        for f in frames:
            self.frames.append(f)
            self._collect(f)
            if f.id == FrameId.SYNC and f.remote and answer is not None:
                reply = answer if isinstance(answer, Frame) else answer(f)
                if reply is not None:
                    self.core.receive(reply.at(f.t_ns + self.latency_ns))
        return frames

    def _collect(self, f: Frame) -> None:
        if f.remote or f.dlc != 8:
            return
        if f.id == FrameId.STATUS:
            self.cycles.append(Cycle(f.t_ns, decode_status(f.data), None))
        elif f.id == FrameId.POSITION and self.cycles:
            last = self.cycles[-1]
            if last.position is None and f.t_ns - last.t_ns <= 40 * MS:
                self.cycles[-1] = Cycle(last.t_ns, last.status, decode_position(f.data))


def joint_move(
    a1: int = 0,
    a2: int = 0,
    a3: int = 0,
    a4: int = 0,
    a5: int = 0,
    a6: int = 0,
    *,
    gripper: int = 0,
    lift: int = 0,
    strict: bool = True,
) -> Frame:
    """A 0x374 frame: motor increments [0.1 deg per 20 ms] (``strict=False`` allows any int8)."""
    cmd = MoveCommand(FrameId.JOINT, lift, (a1, a2, a3, a4, a5, a6), gripper)
    return move_frame(cmd, strict=strict)
