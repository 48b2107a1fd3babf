"""``manus bench drink``: the drink demo's task, 10 seeded runs in lock-step, judged on
the simulator's truth (docs/drink.md).

Each run (seed k = 0..9): the setting of :class:`manus_stack.drink.DrinkSetting` (the
default scene, the arm folded, the shipped cup at a seeded place on the table, the
simulated camera with its noise, latency and dropouts, the user's mouth swaying and
tracked with noise); after 1 s of camera frames the panel's drink task
(:data:`manus_stack.drink.TASK_FILE`) is submitted to the sequencer, the whole stack
running (simulator, bridge, controller, planner, sequencer:
:class:`~manus_stack.task_lockstep.TaskLockStep`). The user says "done" after
:data:`DRINK_S` of holding at the mouth (``TaskControl`` action ``done``). Judged every
20 ms on :class:`~schemas.state.SimTruth` by :class:`~manus_stack.drink.DrinkJudge`:
success is the task's success with 0 contacts, nothing of the arm or the cup inside the
person's clearance, the cup's tilt at most 10 deg and the cup back within 10 mm of where
it stood.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from manus.scene import pose_matrix
from manus_stack.drink import TASK_FILE, DrinkFigures, DrinkJudge, DrinkSetting
from manus_stack.task_lockstep import TaskLockStep
from schemas.sequencing import StepKind, TaskEvent, TaskEventKind
from services.sequencer.taskfile import load_task_file
from services.simulator.config import SimConfig
from services.simulator.objects import SimObject

RUNS = 10
QUICK_RUNS = 2
TICK_S = 0.02
LIMIT_S = 240.0
"""Longest simulated time of one drink [s]."""
DRINK_S = 5.0
"""How long the user drinks, holding at the mouth, before saying "done" [s]."""


def one_run(seed: int) -> DrinkFigures:
    """One drink (see the module docstring): its figures."""
    setting = DrinkSetting.drawn(seed)
    ts = TaskLockStep(SimConfig(objects="none", seed=seed, target=setting.target()))
    sim = ts.ls.sim
    x, y, z = setting.cup_xyz
    cup = SimObject("cup", "cup", "cylinder", (0.040, 0.100), pose_matrix((x, y, z), (0, 0, 0)))
    sim.objects.add(cup)
    judge = DrinkJudge(setting)
    ts.start_arm()
    ts.ls.run_for(1.0)
    task = load_task_file(TASK_FILE)
    follow = next(i for i, s in enumerate(task.steps) if s.kind == StepKind.FOLLOW)
    seen = len(ts.events)
    reply = ts.submit(task, f"drink{seed}")
    if not reply.accepted:
        return _refused(setting, "; ".join(reply.errors))
    end = ts.ls.t_ns + round(LIMIT_S * 1e9)
    holding_since: int | None = None  # when the rim first held at the mouth [ns]
    said = False
    while ts.seq.busy and ts.ls.t_ns < end:
        ts.ls.run_for(TICK_S)
        judge.on_truth(sim.truth())
        for event in ts.events[seen:]:
            judge.on_event(event)
            if holding_since is None and _holding(event, follow):
                holding_since = event.stamp_ns
        seen = len(ts.events)
        if holding_since is not None and not said and ts.ls.t_ns - holding_since >= DRINK_S * 1e9:
            said = ts.control("done") is not None
    for event in ts.events[seen:]:
        judge.on_event(event)
    ts.ls.run_for(1.0)  # the cup put back comes to rest
    judge.on_truth(sim.truth())
    return judge.figures()


def _holding(event: TaskEvent, follow: int) -> bool:
    """The follow step reports progress: its goal holds the standoff point."""
    return event.step == follow and event.event == TaskEventKind.STEP_PROGRESS


def _refused(setting: DrinkSetting, why: str) -> DrinkFigures:
    return DrinkFigures(
        setting.seed, False, f"refused: {why}", {}, 0.0, None, None, 50.0, 0, 0, "", 0.0, None
    )


def run(quick: bool = False) -> dict[str, Any]:
    """Figures of :data:`RUNS` seeded drinks (see the module docstring)."""
    rows = []
    for seed in range(QUICK_RUNS if quick else RUNS):
        started = time.perf_counter()
        row = one_run(seed).row()
        row["wall_s"] = round(time.perf_counter() - started, 2)
        rows.append(row)
    ok = [r for r in rows if r["ok"]]
    arm = [r["arm_min_person_mm"] for r in rows if r["arm_min_person_mm"] is not None]
    cup = [r["cup_min_person_mm"] for r in rows if r["cup_min_person_mm"] is not None]
    placed = [r["placement_error_mm"] for r in rows if r["placement_error_mm"] is not None]
    return {
        "runs": len(rows),
        "succeeded": len(ok),
        "failures": {f"seed {r['seed']}": r["failure"] for r in rows if not r["ok"]},
        "contacts": sum(r["contacts"] + r["person_contacts"] for r in rows),
        "arm_min_person_mm": min(arm) if arm else None,
        "cup_min_person_mm": min(cup) if cup else None,
        "tilt_max_deg": max((r["tilt_max_deg"] for r in rows), default=0.0),
        "placement_error_mm": _stats(placed),
        "task_s": _stats([r["task_s"] for r in ok]),
        "wall_s_per_run": _stats([r["wall_s"] for r in rows]),
        "runs_detail": rows,
    }


def _stats(values: list[float]) -> dict[str, float] | None:
    if not values:
        return None
    a = np.array(values)
    return {
        "median": round(float(np.median(a)), 2),
        "p95": round(float(np.percentile(a, 95)), 2),
        "max": round(float(a.max()), 2),
    }
