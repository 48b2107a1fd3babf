"""A synthetic arm for controller unit tests: integrates the controller's own counts.

Not the simulator: motor angles follow the commanded increments through a first-order
lag, one command per 60 ms cycle, applied one cycle late, exactly as the architecture's
timeline says (the command answering the snapshot at s acts during [s+60, s+120)).
Readings are rounded to 0.1 deg (motors) and 0.1 mm (gripper). Faults are switches:
``stuck`` joints do not move.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from manus.config import UNFOLDED_Q_DEG
from manus.joint_map import dh_to_encoder, encoder_to_dh
from manus.quantize import GRIPPER_COUNT_M_S, RoundingQuantizer, step_rates
from schemas.base import Message
from schemas.commands import JointVelocityCommand
from schemas.control import ControllerFeedback, GoalAck, GoalResult
from schemas.planning import Trajectory
from schemas.state import JointState
from services.can_bridge.commands import to_move
from services.controller.core import ControllerCore
from services.controller.estimator import lag_advance
from services.controller.wiring import WIRING

MS = 1_000_000
CYCLE_NS = 60 * MS
UNIT = math.radians(0.1)
Q0 = np.radians(UNFOLDED_Q_DEG)


def steps(cmd: JointVelocityCommand) -> list[int]:
    """The arm's speed steps a command makes, as the bridge turns it into a 0x374 at the
    CAN edge: lift, motors 1..6 [0.1 deg per 20 ms], gripper [0.1 mm per 20 ms]."""
    move = to_move(cmd, RoundingQuantizer())
    return [move.lift, *move.axes, move.gripper]


def ask(core: ControllerCore, queryable: str, request: Message) -> GoalAck:
    """Ask the controller's queryable (e.g. ``ep.GOAL``) as its shell would."""
    reply, _ = WIRING.answer(queryable).handle(core, request, 0)
    assert isinstance(reply, GoalAck)
    return reply


def feed(core: ControllerCore, suffix: str, msg: Message) -> list[tuple[str, Message]]:
    """Hand the controller one publication (e.g. ``ep.HEARTBEAT``) as its shell would."""
    return WIRING.feed(core, suffix, msg, 0)


@dataclass
class Plant:
    """The fake arm and a log of what the controller published."""

    core: ControllerCore
    q0: np.ndarray = field(default_factory=Q0.copy)
    gripper: float = 0.02
    stuck: set[int] = field(default_factory=set)
    seq: int = 0
    t_ns: int = 1_000 * MS
    commands: list[JointVelocityCommand] = field(default_factory=list)
    feedback: list[ControllerFeedback] = field(default_factory=list)
    results: list[GoalResult] = field(default_factory=list)
    states: list[JointState] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.x = dh_to_encoder(self.q0)
        self.v = np.zeros(6)
        self.g_v = 0.0
        self.active = [0] * 8
        self.pending = [0] * 8

    def joint_state(self) -> JointState:
        """The reading of now (snapshot 20 ms before the stamp)."""
        enc = [round(v / UNIT) for v in self.x]
        g = round(self.gripper / 1e-4)
        q = encoder_to_dh(np.asarray(enc, dtype=float) * UNIT)
        return JointState(
            stamp_ns=self.t_ns + 20 * MS,
            seq=self.seq,
            position=[float(v) for v in q],
            gripper=g * 1e-4,
            valid=True,
            mode="joint",
            encoder=[*enc, g],
            applied_velocity=step_rates(self.active[1:7]),
            applied_gripper_velocity=self.active[7] * GRIPPER_COUNT_M_S,
            applied_kind="joint",
            applied_seq=-1,
        )

    def collect(self, out: list[tuple[str, Message]]) -> None:
        """File the controller's outputs by kind."""
        for key, msg in out:
            if isinstance(msg, JointVelocityCommand):
                assert key == "cmd/joint_velocity"
                self.commands.append(msg)
            elif isinstance(msg, ControllerFeedback):
                self.feedback.append(msg)
            elif isinstance(msg, GoalResult):
                assert key == "controller/result"
                self.results.append(msg)

    def cycle(self, *, skip: bool = False, seq_step: int = 1) -> None:
        """One 60 ms cycle: publish the reading (unless ``skip``), then move."""
        if not skip:
            js = self.joint_state()
            self.states.append(js)
            out = self.core.on_joint_state(js)
            self.collect(out)
            cmds = [m for k, m in out if k == "cmd/joint_velocity"]
            assert len(cmds) == 1 and isinstance(cmds[0], JointVelocityCommand)
            assert cmds[0].ref_seq == js.seq and True
            self.pending = list(steps(cmds[0]))
        else:
            self.pending = [0] * 8
        self.seq += seq_step
        u = np.asarray(self.active[1:7], dtype=float) * math.radians(5.0)
        for j in self.stuck:
            u[j] = 0.0
        x, self.v = lag_advance(self.x, self.v, u, 0.06, 0.02)
        for j in self.stuck:
            x[j] = self.x[j]
            self.v[j] = 0.0
        self.x = x
        gx, gv = lag_advance(
            np.array([self.gripper]),
            np.array([self.g_v]),
            np.array([self.active[7] * 0.005]),
            0.06,
            0.02,
        )
        self.gripper, self.g_v = float(np.clip(gx[0], 0.0, 0.09)), float(gv[0])
        self.t_ns += CYCLE_NS
        self.active, self.pending = self.pending, [0] * 8

    def run(self, cycles: int) -> None:
        """Several cycles."""
        for _ in range(cycles):
            self.cycle()

    def run_until_result(self, goal_id: str, limit: int = 2000) -> GoalResult:
        """Cycle until ``goal_id`` has its result."""
        for _ in range(limit):
            done = [r for r in self.results if r.goal_id == goal_id]
            if done:
                return done[0]
            self.cycle()
        raise AssertionError(f"no result for {goal_id} within {limit} cycles")

    @property
    def q(self) -> np.ndarray:
        """True DH angles now [rad]."""
        return np.asarray(encoder_to_dh(self.x))


def line_trajectory(
    q0: np.ndarray, delta_deg: tuple[float, ...], duration: float, knots: int = 5
) -> Trajectory:
    """A straight joint-space move with rest at both ends (cubic Hermite, smoothstep)."""
    d = np.radians(np.asarray(delta_deg, dtype=float))
    ts = np.linspace(0.0, duration, knots)
    s = ts / duration
    pos = [q0 + d * (3 * si**2 - 2 * si**3) for si in s]
    vel = [d * (6 * si - 6 * si**2) / duration for si in s]
    return Trajectory(
        times=[float(t) for t in ts],
        positions=[[float(v) for v in p] for p in pos],
        velocities=[[float(v) for v in p] for p in vel],
    )
