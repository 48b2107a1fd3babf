"""``manus bench pick``: fetch the cup, in lock-step, judged on the simulator's truth.

Each run (seed k = 0, 1, ...): the default scene, the arm unfolded, the shipped cup
(radius 40 mm, 100 mm tall) at a seeded position on the table, in every third run a
bottle beside it (110-150 mm away, centre to centre, to its left or right within 60 deg
as the camera sees it), the simulated camera on with its
noise, latency and dropouts (the stack sees only what it publishes). After 1 s of
camera frames a task of two steps is submitted to the sequencer: ``pick cup`` and
``place cup at`` a seeded target on the table (at least 150 mm from where the cup and
the bottle stand). The whole stack runs (simulator, bridge, controller, planner,
sequencer: :class:`manus_stack.task_lockstep.TaskLockStep`) until the task ends.

Judged every 20 ms on :class:`~schemas.state.SimTruth`, never on what the stack says:

- **success**: the task succeeded, the cup rests on the table, upright, within
  :data:`PLACE_TOLERANCE_M` of the target; every other run is a failure with its reason
  (the task's, or what the truth shows);
- **placement error**: the cup's centre to the target, horizontally [mm];
- **the person**: contacts of the arm or the held cup with any person body (the truth's
  object contacts of class ``person`` and the arm's contacts with a person body), and the
  held cup's smallest distance to the person (``held_min_person``);
- **tilt**: the held cup's largest lean from upright while held [deg];
- **time**: simulated time from the submission to the task's end [s], and the wall time
  of the whole run (validation planning included).
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from manus.grasp_poses import tilt
from manus.orientation import ypr_to_matrix
from manus.scene import default_scene, pose_matrix
from manus_stack.task_lockstep import TaskLockStep
from schemas.objects import ContactClass
from schemas.sequencing import StepKind, Task, TaskState, TaskStep
from schemas.state import SimTruth
from services.simulator.config import SimConfig
from services.simulator.objects import SimObject

RUNS = 30
QUICK_RUNS = 4
TABLE_TOP = 0.74
"""The default scene's table top [m]."""
CUP_RADIUS, CUP_LENGTH = 0.040, 0.100
AREA = ((0.86, 1.00), (-0.25, -0.05))
"""Where cups are drawn from: x, y ranges on the table, chair frame [m] (the camera's view
of the table has a blind band at y -0.30..-0.40 m behind the user's right arm)."""
TARGETS = ((0.84, 0.96), (-0.42, -0.05))
"""Where targets are drawn from [m]."""
PLACE_TOLERANCE_M = 0.010
TICK_S = 0.02
LIMIT_S = 120.0
"""Longest simulated time of one task [s]."""


def _draw(
    rng: np.random.Generator,
    away: list[np.ndarray],
    gap: float,
    area: tuple[tuple[float, float], tuple[float, float]] = AREA,
) -> np.ndarray:
    """A point of ``area`` at least ``gap`` from every point of ``away``."""
    while True:
        p = np.array([rng.uniform(*area[0]), rng.uniform(*area[1])])
        if all(np.linalg.norm(p - a) >= gap for a in away):
            return p


def _cup(xy: np.ndarray) -> SimObject:
    pose = pose_matrix((float(xy[0]), float(xy[1]), TABLE_TOP + CUP_LENGTH / 2), (0.0, 0.0, 0.0))
    return SimObject("cup", "cup", "cylinder", (CUP_RADIUS, CUP_LENGTH), pose)


def _bottle(rng: np.random.Generator, cup: np.ndarray) -> SimObject:
    """A bottle beside the cup as the camera sees it (to its left or right, not in front
    of it or behind it: in front, it hides the cup and the pick is refused, the cup
    unknown)."""
    while True:
        turn = rng.choice([-1.0, 1.0]) * math.pi / 2 + rng.uniform(-math.pi / 3, math.pi / 3)
        xy = cup + rng.uniform(0.11, 0.15) * np.array([math.cos(turn), math.sin(turn)])
        if AREA[0][0] - 0.04 <= xy[0] <= 1.30 and -0.48 <= xy[1] <= 0.40:
            break
    pose = pose_matrix((float(xy[0]), float(xy[1]), TABLE_TOP + 0.11), (0.0, 0.0, 0.0))
    return SimObject("bottle", "bottle", "cylinder", (0.035, 0.22), pose)


def one_run(seed: int) -> dict[str, Any]:
    """One pick and place (see the module docstring); its figures."""
    rng = np.random.default_rng(seed)
    started = time.perf_counter()
    ts = TaskLockStep(SimConfig(start_pose="unfolded", objects="none", seed=seed))
    sim = ts.ls.sim
    cup_xy = _draw(rng, [], 0.0)
    sim.objects.add(_cup(cup_xy))
    away = [cup_xy]
    beside = seed % 3 == 2
    if beside:
        bottle = _bottle(rng, cup_xy)
        sim.objects.add(bottle)
        away.append(bottle.pose[:2, 3])
    target = _draw(rng, away, 0.15, TARGETS)
    ts.start_arm()
    ts.ls.run_for(1.0)
    at = [float(target[0]), float(target[1]), TABLE_TOP + CUP_LENGTH / 2, 0.0, 0.0, 0.0]
    task = Task(
        steps=[
            TaskStep(kind=StepKind.PICK, object="cup"),
            TaskStep(kind=StepKind.PLACE, object="cup", at=at),
        ],
        name="bench pick",
    )
    t0 = ts.ls.t_ns
    reply = ts.submit(task, f"pick{seed}")
    worst_tilt = 0.0
    if reply.accepted:
        end = t0 + round(LIMIT_S * 1e9)
        while ts.seq.busy and ts.ls.t_ns < end:
            ts.ls.run_for(TICK_S)
            worst_tilt = max(worst_tilt, _held_tilt(sim.truth()))
    t1 = ts.ls.t_ns
    ts.ls.run_for(1.0)  # let a released cup come to rest
    truth = sim.truth()
    return _judge(ts, truth, reply.errors, target, worst_tilt, beside, seed) | {
        "task_s": round((t1 - t0) / 1e9, 2),
        "wall_s": round(time.perf_counter() - started, 2),
    }


def _held_tilt(truth: SimTruth) -> float:
    cup = next((o for o in truth.objects if o.id == "cup"), None)
    if cup is None or not cup.held:
        return 0.0
    return tilt(ypr_to_matrix(cup.ypr[0], cup.ypr[1], cup.ypr[2]))


def _person(truth: SimTruth) -> int:
    people = {o.name for o in default_scene().objects if o.cls == ContactClass.PERSON}
    held = sum(1 for c in truth.object_contacts if c.cls == ContactClass.PERSON)
    arm = 1 if truth.contact.split("/")[-1] in people else 0
    return held + arm


def _judge(
    ts: TaskLockStep,
    truth: SimTruth,
    refused: list[str],
    target: np.ndarray,
    worst_tilt: float,
    beside: bool,
    seed: int,
) -> dict[str, Any]:
    cup = next(o for o in truth.objects if o.id == "cup")
    error = float(np.linalg.norm(np.array(cup.xyz[:2]) - target))
    state = ts.seq.state
    if refused:
        why = "refused: " + "; ".join(refused)
    elif state != TaskState.SUCCEEDED:
        why = f"task {state}: {ts.seq.reason}"
    elif cup.held or cup.resting_on != "table":
        why = f"the cup is not on the table ({'held' if cup.held else cup.resting_on or 'falling'})"
    elif error > PLACE_TOLERANCE_M:
        why = f"placed {error * 1e3:.1f} mm from the target"
    else:
        why = ""
    return {
        "seed": seed,
        "beside_bottle": beside,
        "ok": not why,
        "failure": why,
        "placement_error_mm": round(error * 1e3, 2),
        "tilt_max_deg": round(math.degrees(worst_tilt), 2),
        "held_min_person_mm": (
            round(truth.held_min_person * 1e3, 1) if truth.held_min_person is not None else None
        ),
        "person_contacts": _person(truth),
        "slips": cup.slips,
    }


def run(quick: bool = False) -> dict[str, Any]:
    """Figures of :data:`RUNS` seeded picks and places (see the module docstring)."""
    runs = [one_run(seed) for seed in range(QUICK_RUNS if quick else RUNS)]
    ok = [r for r in runs if r["ok"]]
    placed = [
        r["placement_error_mm"] for r in runs if r["failure"] == "" or "placed" in r["failure"]
    ]
    near = [r["held_min_person_mm"] for r in runs if r["held_min_person_mm"] is not None]
    times = [r["task_s"] for r in ok]
    return {
        "runs": len(runs),
        "succeeded": len(ok),
        "success_rate": round(len(ok) / len(runs), 3),
        "failures": {f"seed {r['seed']}": r["failure"] for r in runs if not r["ok"]},
        "placement_error_mm": _stats(placed),
        "tilt_max_deg_held": max((r["tilt_max_deg"] for r in runs), default=0.0),
        "person_contacts": sum(r["person_contacts"] for r in runs),
        "held_min_person_mm": min(near) if near else None,
        "task_s": _stats(times),
        "wall_s_per_run": _stats([r["wall_s"] for r in runs]),
        "runs_detail": runs,
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
