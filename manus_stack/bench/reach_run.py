"""Running the goal set of ``manus bench reach`` in-process: the planner core
(:class:`services.planner.core.PlannerCore`, as the planner service runs it) on every
goal, from its start.

Each goal starts at a named pose or where an earlier goal's plan (seed 1) ends, so the
set is planned in file order. A run is timed whole (goal states, search, simplification,
time parametrisation, limit checks and the sweep of the final trajectory), on the wall
clock and in the process's CPU time: on a shared machine the wall clock also counts the
time other processes hold the cores, the CPU time does not.
"""

from __future__ import annotations

import dataclasses
import time
from typing import NamedTuple

import numpy as np

from manus.collision import CollisionModel
from manus.named_poses import NamedPose, named_poses
from manus_stack.bench.reach_set import BenchGoal
from schemas.goals import JointGoal, NamedGoal, ObjectGoal, PoseGoal, Search
from schemas.planning import PlanError, PlanRequest, Trajectory
from services.planner.config import PlannerConfig
from services.planner.core import PlannerCore


class Outcome(NamedTuple):
    """One plan of one goal.

    Attributes:
        goal: the goal.
        start: where it started [rad], shape (6,).
        seconds: how long planning took, wall clock [s].
        cpu_seconds: the process's CPU time while planning [s].
        trajectory: the plan (None: refused).
        error: the refusal (None: planned).
    """

    goal: BenchGoal
    start: np.ndarray
    seconds: float
    cpu_seconds: float
    trajectory: Trajectory | None
    error: PlanError | None

    @property
    def right(self) -> bool:
        """Planned when feasible, refused with the expected reason when not."""
        if self.goal.refused:
            return self.error is not None and self.error.reason == self.goal.refused
        return self.trajectory is not None


class Planning:
    """The default scene, the shipped poses and the planner's settings, ready to plan."""

    def __init__(self, config: PlannerConfig | None = None) -> None:
        self.config = config or PlannerConfig(scene="default", poses="")
        self.core = PlannerCore(self.config)
        assert self.core.collision is not None
        self.model: CollisionModel = self.core.collision
        self.poses: dict[str, NamedPose] = named_poses(self.config.poses)

    def request(self, goal: BenchGoal, start: np.ndarray, seed: int = 1) -> PlanRequest:
        """The plan request of ``goal`` from ``start`` [rad] with ``seed``."""
        motion = goal.goal
        if isinstance(motion, JointGoal | PoseGoal | NamedGoal | ObjectGoal):
            motion = dataclasses.replace(motion, search=Search(seed=seed))
        return PlanRequest(motion, start=[float(v) for v in start], preview_dt=0.0)

    def plan(self, goal: BenchGoal, start: np.ndarray, seed: int = 1) -> Outcome:
        """Plan ``goal`` from ``start`` with ``seed``, timed."""
        request = self.request(goal, start, seed)
        started, cpu = time.perf_counter(), time.process_time()
        reply = self.core.plan(request)
        wall, cpu = time.perf_counter() - started, time.process_time() - cpu
        return Outcome(goal, start, wall, cpu, reply.trajectory, reply.error)

    def run_set(self, goals: list[BenchGoal], seed: int = 1) -> list[Outcome]:
        """Every goal in file order, each from its start (see the module docstring)."""
        ends: dict[str, np.ndarray] = {}
        out = []
        for goal in goals:
            outcome = self.plan(goal, self.start_of(goal, ends), seed)
            if outcome.trajectory is not None:
                ends[goal.id] = np.array(outcome.trajectory.positions[-1])
            out.append(outcome)
        return out

    def start_of(self, goal: BenchGoal, ends: dict[str, np.ndarray]) -> np.ndarray:
        """The start configuration of ``goal`` [rad]."""
        if goal.start in ends:
            return ends[goal.start]
        named = self.poses[goal.start]
        assert named.joints is not None, f"{goal.start}: a start must be a configuration"
        return np.array(named.joints)


def path_length(trajectory: Trajectory) -> float:
    """Joint-space length of a trajectory's knot polyline [rad] (Euclidean per step)."""
    q = np.asarray(trajectory.positions, dtype=float)
    return float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum())


def stats_ms(seconds: list[float]) -> dict[str, float]:
    """p50, p95 and largest of ``seconds``, in ms."""
    if not seconds:
        return {"p50_ms": 0.0, "p95_ms": 0.0, "max_ms": 0.0, "runs": 0}
    a = np.asarray(seconds) * 1e3
    return {
        "p50_ms": round(float(np.percentile(a, 50)), 2),
        "p95_ms": round(float(np.percentile(a, 95)), 2),
        "max_ms": round(float(a.max()), 2),
        "runs": len(seconds),
    }


def start_of_all(
    planning: Planning, goals: list[BenchGoal], base: list[Outcome]
) -> dict[str, np.ndarray]:
    """Each goal's start [rad], by id (the starts ``base``, a seed-1 pass, planned from)."""
    return {o.goal.id: o.start for o in base}
