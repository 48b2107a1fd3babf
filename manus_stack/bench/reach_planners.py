"""Which OMPL planner: each candidate on the goals of the set that need a search.

A goal needs a search when no straight joint motion to its nearest goal states is clear
(its seed-1 plan says so). For each such goal and each candidate, seeds 1..5 with the
same iteration budget: how often a path is found, the time the search takes (the
direct tries, the search and its shortening), and the joint path length relative to
the shortest any candidate found for that goal. Candidates are OMPL's geometric
planners that return at their first solution (RRTConnect with OMPL's default range and
shorter ones, RRT, the KPIECE family), each with one search, and RRTConnect as the
planner runs it (searches for a shorter path while the first is a detour); the
asymptotically optimal ones (RRT*, AORRTC, BIT*) use their whole budget by design and
are left out of a first-solution race.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from manus.config import DEFAULT_ARM
from manus_stack.bench.reach_run import Outcome, Planning, start_of_all, stats_ms
from manus_stack.bench.reach_set import BenchGoal
from schemas.goals import JointGoal, NamedGoal, ObjectGoal, PoseGoal
from services.planner.errors import PlanningError
from services.planner.goal_planner import validity_of
from services.planner.goal_states import goal_states
from services.planner.goal_target import resolve_target
from services.planner.search import SEARCHES, Found, SearchSettings, search
from services.planner.work_area import WorkArea

CANDIDATES: tuple[tuple[str, float, int], ...] = (
    ("RRTConnect", 0.0, 1),
    ("RRTConnect", 1.0, 1),
    ("RRTConnect", 0.5, 1),
    ("RRT", 0.0, 1),
    ("LBKPIECE1", 0.0, 1),
    ("BKPIECE1", 0.0, 1),
    ("KPIECE1", 0.0, 1),
    ("RRTConnect", 1.0, SEARCHES),
)
"""(planner, range [rad], most searches) measured; range 0: OMPL's default; one search:
the first path found, shortened; :data:`~services.planner.search.SEARCHES`: as the
planner plans (more searches for a shorter path while the first is a detour)."""

SEEDS = range(1, 6)


def compare(planning: Planning, goals: list[BenchGoal], base: list[Outcome]) -> dict[str, Any]:
    """The candidates' figures on the goals whose seed-1 plan needed a search."""
    starts = start_of_all(planning, goals, base)
    hard = [
        o.goal
        for o in base
        if not o.goal.refused and (o.trajectory is None or "RRTConnect" in o.trajectory.notes[0])
    ]
    fast, exact = validity_of(planning.model)
    arm = DEFAULT_ARM
    work = WorkArea(arm)
    problems = []
    for goal in hard:
        assert isinstance(goal.goal, JointGoal | PoseGoal | NamedGoal | ObjectGoal)
        target = resolve_target(goal.goal, planning.model.scene, planning.poses)
        try:
            states = goal_states(target, starts[goal.id], arm, exact, planning.model.scene, 1, work)
        except PlanningError:
            continue
        problems.append((goal.id, starts[goal.id], states))
    table: dict[str, Any] = {}
    lengths: dict[tuple[str, str], list[float]] = {}
    for name, reach, searches in CANDIDATES:
        label = name if reach == 0.0 else f"{name} range {reach:g}"
        if searches > 1:
            label += f", up to {searches} searches (as planned)"
        times, found = [], 0
        for gid, start, states in problems:
            for seed in SEEDS:
                settings = SearchSettings(
                    seed=seed, budget=3000, planner=name, range=reach, searches=searches
                )
                started = time.perf_counter()
                result = search(
                    start, states, (fast, exact), work, arm.lower_array, arm.upper_array, settings
                )
                times.append(time.perf_counter() - started)
                if isinstance(result, Found):
                    found += 1
                    q = result.path
                    length = float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum())
                    lengths.setdefault((label, gid), []).append(length)
        table[label] = {"found": found, "of": len(problems) * len(SEEDS), "time": stats_ms(times)}
    for label, row in table.items():
        ratios = []
        for gid, _, _ in problems:
            best = min((min(v) for (lab, g), v in lengths.items() if g == gid), default=None)
            ratios += [x / best for x in lengths.get((label, gid), [])] if best else []
        row["length_over_best_p50"] = round(float(np.median(ratios)), 3) if ratios else None
    return {"goals": [p[0] for p in problems], "seeds": len(SEEDS), "candidates": table}
