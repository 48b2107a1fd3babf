"""Goals of ``manus bench reach`` executed on the simulator in lock-step, judged on its
truth.

For each goal: a simulated arm powered up at the goal's start configuration, with the
bridge and the controller (:class:`manus_stack.controlled.ControlledArm`); the goal is
planned from the arm's first valid joint state (encoder-quantised, so not exactly the
start), sent as a trajectory goal and run to its result. At every 20 ms tick the
simulator's true joint angles (:class:`schemas.state.SimTruth`, never what the stack
reports) are judged by the exact collision model with each class's clearance
(:meth:`manus.collision.CollisionModel.clearance`): the smallest true margin (distance
minus the class clearance, the zones included) must stay at or above 0, and the
simulator must count no contact.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from manus_stack.bench.reach_run import Planning
from manus_stack.bench.reach_set import BenchGoal
from manus_stack.controlled import ControlledArm
from schemas.control import TrajectoryGoal
from services.simulator.config import SimConfig

TICK_S = 0.02
"""How often the truth is judged [s] (the simulator's tick)."""

AFTER_S = 1.0
"""How long the arm is watched after the goal's result [s]."""


class Executed(NamedTuple):
    """One goal run on the simulator.

    Attributes:
        goal: the goal's id.
        status: the controller's result (``succeeded``, ``aborted``, ...; ``refused``:
            not planned from the arm's joint state).
        reason: the result's reason.
        margin: the smallest true margin over the run [m] (distance minus the class
            clearance, zones included).
        tightest: that check, in words.
        contacts: contacts the simulator counted.
        final_error: gripper position error at the end [m].
    """

    goal: str
    status: str
    reason: str
    margin: float
    tightest: str
    contacts: int
    final_error: float


def execute(planning: Planning, goal: BenchGoal, start: np.ndarray) -> Executed:
    """Run ``goal`` from ``start`` [rad] on the simulator (see the module docstring)."""
    arm = ControlledArm(SimConfig(start_pose=tuple(float(v) for v in np.degrees(start))))
    js = arm.start()
    outcome = planning.plan(goal, np.array(js.position))
    if outcome.trajectory is None:
        reason = outcome.error.message if outcome.error is not None else ""
        return Executed(goal.id, "refused", reason, math.nan, "", 0, math.nan)
    ack = arm.submit(TrajectoryGoal(goal_id=goal.id, trajectory=outcome.trajectory))
    if not ack.accepted:
        return Executed(goal.id, "not accepted", ack.reason, math.nan, "", 0, math.nan)
    model = planning.model
    worst, tightest = math.inf, ""
    limit = arm.ls.t_ns + round((outcome.trajectory.times[-1] + 10.0) * 1e9)
    done_at: int | None = None
    contacts = 0
    while arm.ls.t_ns < limit and (done_at is None or arm.ls.t_ns < done_at):
        arm.ls.run_for(TICK_S)
        truth = arm.ls.sim.truth()
        contacts = truth.contacts
        found = model.clearance(np.array(truth.q_true))
        if found.margin < worst:
            worst, tightest = found.margin, found.describe()
        if done_at is None and arm.results(goal.id):
            done_at = arm.ls.t_ns + round(AFTER_S * 1e9)
    results = arm.results(goal.id)
    if not results:
        return Executed(goal.id, "no result", "", worst, tightest, contacts, math.nan)
    result = results[0]
    return Executed(
        goal.id, result.status, result.reason, worst, tightest, contacts, result.final_error
    )
