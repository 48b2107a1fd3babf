"""Sequencer figures: whole-task validation time, and the demo task in lock-step.

- ``validate``: the demo task (fold out, thesis path, gripper close/open, fold in)
  validated in-process with :class:`~services.planner.core.PlannerCore` answering the
  plan requests (the Zenoh round trips of ``manus bench plan`` come on top).
- ``demo_<path>``: the demo task run by the sequencer core driving the real controller,
  bridge and simulator cores in lock-step (:mod:`manus_stack.task_lockstep`): outcome,
  simulated and CPU time, via-point errors of the path (``GoalResult.via_errors``, the
  start knot excluded).
- ``pause_resume_square``: the square paused 7 s in, held 2 s, resumed: distance from
  the final gripper position to the square's last via point.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from manus.config import DEFAULT_ARM
from manus.kinematics import fk
from manus_stack.demo import demo_task
from manus_stack.task_lockstep import NS, TaskLockStep
from schemas.control import TrajectoryGoal
from schemas.sequencing import Task, TaskStep
from services.planner.core import PlannerCore
from services.sequencer.validate import Validator


def _validate(task: Task, runs: int) -> dict[str, Any]:
    planner = PlannerCore()
    start = list(np.radians([0.0, -90.0, -90.0, 0.0, -90.0, 0.0]))  # folded, as powered up
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        v = Validator(task, start, DEFAULT_ARM)
        while (request := v.next_request()) is not None:
            v.on_reply(planner.plan(request))
        times.append(time.perf_counter() - t0)
        assert not v.errors, v.errors
    a = np.asarray(times) * 1e3
    return {"p50_ms": round(float(np.median(a)), 3), "max_ms": round(float(a.max()), 3),
            "runs": runs}  # fmt: skip


def _demo(shape: str) -> dict[str, Any]:
    cpu = time.process_time()
    rig = TaskLockStep()
    rig.start_arm()
    t0 = rig.ls.t_ns
    reply = rig.submit(demo_task(shape))
    if not reply.accepted:
        return {"refused": reply.errors}
    rig.run_while_busy()
    paths = [r for r in rig.results() if r.kind == "trajectory"]
    errors = np.asarray(paths[0].via_errors[1:]) * 1e3 if paths else np.zeros(0)
    return {
        "state": rig.seq.state,
        "reason": rig.seq.reason,
        "task_s": round((rig.ls.t_ns - t0) / NS, 2),
        "cpu_s": round(time.process_time() - cpu, 2),
        "via_mean_mm": round(float(errors.mean()), 3) if errors.size else None,
        "via_max_mm": round(float(errors.max()), 3) if errors.size else None,
        "events": len(rig.events),
    }


def _pause_resume() -> dict[str, Any]:
    rig = TaskLockStep()
    rig.start_arm()
    rig.submit(Task(steps=[TaskStep(kind="fold_out")]))
    rig.run_while_busy()
    task = demo_task("square")
    rig.submit(Task(steps=[task.steps[1]]), task_id="square")
    rig.ls.run_for(7.0)
    rig.control("pause")
    rig.run_until_event("paused")
    rig.ls.run_for(2.0)
    rig.control("resume")
    rig.run_while_busy()
    goals = [r for r in rig.requests if isinstance(r, TrajectoryGoal)]
    final = rig.joint_states()[-1][1]
    end = np.asarray(goals[0].trajectory.via_xyz[-1])
    miss = float(np.linalg.norm(fk(final.position, DEFAULT_ARM)[:3, 3] - end)) * 1e3
    return {"state": rig.seq.state, "goals": len(goals), "end_error_mm": round(miss, 3)}


def run(quick: bool = False) -> dict[str, Any]:
    """The figures (see the module docstring)."""
    return {
        "validate_demo_square": _validate(demo_task("square"), 20 if quick else 200),
        "validate_demo_circle": _validate(demo_task("circle"), 20 if quick else 200),
        "demo_square": _demo("square"),
        "demo_circle": _demo("circle"),
        "pause_resume_square": _pause_resume(),
        "thesis": {"via_mean_mm": 5.0, "via_max_mm": 10.0},
    }
