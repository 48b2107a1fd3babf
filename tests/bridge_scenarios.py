"""Helpers for the bridge tests: a scripted controller and the safety invariants."""

from __future__ import annotations

import math
from collections.abc import Sequence

from manus.protocol import FrameId, decode_move
from manus_stack.lockstep import LockStep
from schemas.base import Message
from schemas.commands import JointVelocityCommand
from schemas.state import BridgeState, JointState
from services.simulator.config import SimConfig

UNFOLDED = SimConfig(start_pose="unfolded")
MS = 1_000_000


class VelocityController:
    """Answers every valid joint state with fixed DH velocities [deg/s].

    Attributes:
        stop_after_ns: stop answering (as a crashed controller would) from this time on.
        lag: answer the state this many states older (a late controller).
    """

    def __init__(
        self,
        deg_s: Sequence[float] = (10.0, 0, 0, 0, 0, 0),
        *,
        gripper_m_s: float = 0.0,
        ref_seq_none: bool = False,
    ) -> None:
        self.deg_s = list(deg_s)
        self.gripper_m_s = gripper_m_s
        self.ref_seq_none = ref_seq_none
        self.stop_after_ns: int | None = None
        self.lag = 0
        self.sent: list[JointVelocityCommand] = []
        self._states: list[JointState] = []

    def __call__(self, msg: Message, t_ns: int) -> list[tuple[str, Message]]:
        assert isinstance(msg, JointState)
        self._states.append(msg)
        if not msg.valid or (self.stop_after_ns is not None and t_ns >= self.stop_after_ns):
            return []
        if len(self._states) <= self.lag:
            return []
        ref = self._states[-1 - self.lag]
        cmd = JointVelocityCommand(
            stamp_ns=ref.stamp_ns,
            seq=len(self.sent),
            source="test",
            ref_seq=-1 if self.ref_seq_none else ref.seq,
            velocity=[math.radians(v) for v in self.deg_s],
            gripper_velocity=self.gripper_m_s,
        )
        self.sent.append(cmd)
        return [("cmd/joint_velocity", cmd)]


def running(sim: SimConfig = UNFOLDED, *, reply_latency_ns: int = MS) -> LockStep:
    """A lock-step run with the bridge already in phase ``running``."""
    ls = LockStep(sim, reply_latency_ns=reply_latency_ns)
    ls.run_until_phase("running", timeout_s=3.0)
    return ls


def moves(ls: LockStep, since_ns: int = 0) -> list[tuple[int, tuple[int, ...]]]:
    """(send time, the 8 increments) of every 0x374 the bridge sent since ``since_ns``."""
    out: list[tuple[int, tuple[int, ...]]] = []
    for f in ls.bridge_frames:
        if f.id == FrameId.JOINT and f.t_ns >= since_ns:
            m = decode_move(f.id, f.data)
            out.append((f.t_ns, (m.lift, *m.axes, m.gripper)))
    return out


def phases(ls: LockStep, since_ns: int = 0) -> list[str]:
    """The bridge phases published since ``since_ns``, consecutive repeats removed."""
    seen: list[str] = []
    for t, _, m in ls.messages:
        if isinstance(m, BridgeState) and t >= since_ns and (not seen or seen[-1] != m.phase):
            seen.append(m.phase)
    return seen


def check_safety(ls: LockStep) -> None:
    """Invariants of every run.

    - exactly one bridge frame per sync it answered, each sent at its sync's time;
    - a non-zero move is only sent at a sync whose cycle published a joint state
      (20 ms earlier) while the bridge was running or initialising.
    """
    syncs = {f.t_ns for f in ls.arm_frames if f.id == FrameId.SYNC}
    sent_at = [f.t_ns for f in ls.bridge_frames]
    assert len(sent_at) == len(set(sent_at)), "two frames at one sync"
    states = {m.stamp_ns for t, s, m in ls.messages if isinstance(m, JointState)}
    for t, incs in moves(ls):
        assert t in syncs, f"a move at {t / 1e6} ms answered no sync"
        if any(incs):
            assert t - 20 * MS in states, f"a move at {t / 1e6} ms without this cycle's state"
    counters = ls.sim.counters
    assert counters.extra_replies == 0
