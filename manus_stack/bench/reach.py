"""``manus bench reach``: goal planning on the fixed goal set (``reach_goals.yaml``).

- ``in_process``: every goal planned by the planner core's goal planning, each feasible
  one with seeds 1..10 (``--quick``: 1..3), timed whole (wall clock and CPU time); success
  rate and planning time of the feasible goals; for the infeasible ones, whether each was
  refused with the reason the set names, and how fast.
- ``quality``: per feasible goal, each seed's joint path length (the knots' polyline,
  Euclidean in joint space) over the shortest of its seeds.
- ``planner_service``: the same plans through ``manus planner`` in its own process, over
  a loopback router (:mod:`manus_stack.bench.reach_service`).
- ``lockstep``: a sample of the feasible goals (every second one; ``--quick``: every
  sixth) run on the simulator in lock-step and judged on its truth
  (:mod:`manus_stack.bench.reach_lockstep`).
- ``validity``: the collision check the search uses (:mod:`manus.validity`) against the
  exact one (Coal), per configuration, in the same run.
- ``planners`` (not with ``--quick``): the OMPL planners measured on the goals that need
  a search (:mod:`manus_stack.bench.reach_planners`), which chose RRTConnect.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from typing import Any

import numpy as np

from manus.config import DEFAULT_ARM
from manus.validity import checker_for
from manus_stack.bench.reach_lockstep import execute
from manus_stack.bench.reach_run import Outcome, Planning, path_length, stats_ms
from manus_stack.bench.reach_service import round_trips
from manus_stack.bench.reach_set import load_goal_set

TARGET = (
    "feasible: success >= 99 %, plan p50 <= 20 ms, p95 <= 100 ms; infeasible: refused "
    "with the right reason, p95 <= 50 ms; path length <= 1.3x the shortest of 10 seeds; "
    "lock-step: 0 contacts, smallest true margin >= 0 (clearance kept)"
)


def run(quick: bool = False) -> dict[str, Any]:
    """Figures of goal planning (see the module docstring)."""
    planning = Planning()
    goals = load_goal_set()
    first = time.perf_counter()
    base = planning.run_set(goals, seed=1)  # seed 1; also warms up the compiled checks
    first_s = time.perf_counter() - first
    seeds = range(1, 4 if quick else 11)
    runs: dict[str, list[Outcome]] = {o.goal.id: [o] for o in base}
    for seed in seeds[1:]:
        for outcome in planning.run_set(goals, seed=seed):
            runs[outcome.goal.id].append(outcome)
    out: dict[str, Any] = {
        "goals": _census(base),
        "first_pass_s": round(first_s, 2),
        "in_process": _in_process(runs),
        "quality": _quality(runs),
        "planner_service": round_trips(planning, base, 1 if quick else 3),
        "lockstep": _lockstep(planning, base, 6 if quick else 2),
        "validity": _validity(planning, 500 if quick else 2000),
        "target": TARGET,
    }
    if not quick:
        from manus_stack.bench.reach_planners import compare

        out["planners"] = compare(planning, goals, base)
    return out


def _census(base: list[Outcome]) -> dict[str, Any]:
    areas = Counter(o.goal.area for o in base)
    return {
        "total": len(base),
        "feasible": sum(1 for o in base if not o.goal.refused),
        "infeasible": sum(1 for o in base if o.goal.refused),
        "by_area": dict(areas),
        "needing_a_search": sum(
            1 for o in base if o.trajectory is not None and "RRTConnect" in o.trajectory.notes[0]
        ),
    }


def _in_process(runs: dict[str, list[Outcome]]) -> dict[str, Any]:
    feasible = [o for rs in runs.values() for o in rs if not o.goal.refused]
    infeasible = [rs[0] for rs in runs.values() if rs[0].goal.refused]
    failed = sorted({o.goal.id for o in feasible if o.trajectory is None})
    wrong = [
        {
            "goal": o.goal.id,
            "expected": o.goal.refused,
            "got": o.error.reason if o.error is not None else "planned",
        }
        for o in infeasible
        if not o.right
    ]
    return {
        "feasible": {
            "runs": len(feasible),
            "success_rate": round(
                sum(o.trajectory is not None for o in feasible) / len(feasible), 4
            ),
            "not_planned": failed,
            "plan_time": stats_ms([o.seconds for o in feasible]),
            "plan_cpu_time": stats_ms([o.cpu_seconds for o in feasible]),
            "slowest_goals": _slowest(feasible),
        },
        "infeasible": {
            "goals": len(infeasible),
            "right_reason": sum(o.right for o in infeasible),
            "wrong": wrong,
            "refusal_time": stats_ms([o.seconds for o in infeasible]),
            "refusal_cpu_time": stats_ms([o.cpu_seconds for o in infeasible]),
            "reasons": dict(Counter(o.error.reason for o in infeasible if o.error is not None)),
        },
    }


def _slowest(outcomes: list[Outcome], n: int = 5) -> list[dict[str, Any]]:
    """The ``n`` goals with the largest CPU time of a plan [ms], its median, and the most
    knots of their plans (2: a straight joint motion)."""
    by_goal: dict[str, list[Outcome]] = {}
    for o in outcomes:
        by_goal.setdefault(o.goal.id, []).append(o)
    worst = sorted(by_goal.items(), key=lambda kv: -max(o.cpu_seconds for o in kv[1]))
    return [
        {
            "goal": gid,
            "cpu_max_ms": round(max(o.cpu_seconds for o in os_) * 1e3, 1),
            "cpu_p50_ms": round(float(np.median([o.cpu_seconds for o in os_])) * 1e3, 1),
            "knots_max": max(
                (len(o.trajectory.times) for o in os_ if o.trajectory is not None), default=0
            ),
        }
        for gid, os_ in worst[:n]
    ]


def _quality(runs: dict[str, list[Outcome]]) -> dict[str, Any]:
    ratios: list[float] = []
    worst: list[tuple[float, str]] = []
    for gid, outcomes in runs.items():
        lengths = [path_length(o.trajectory) for o in outcomes if o.trajectory is not None]
        if len(lengths) < 2 or outcomes[0].goal.refused:
            continue
        shortest = min(lengths)
        mine = [length / shortest if shortest > 0 else 1.0 for length in lengths]
        ratios += mine
        worst.append((max(mine), gid))
    a = np.asarray(ratios)
    worst.sort(reverse=True)
    return {
        "runs": len(ratios),
        "within_1_3x": round(float((a <= 1.3).mean()), 4) if len(a) else 1.0,
        "ratio_p95": round(float(np.percentile(a, 95)), 3) if len(a) else 1.0,
        "ratio_max": round(float(a.max()), 3) if len(a) else 1.0,
        "worst_goals": [{"goal": g, "ratio": round(r, 3)} for r, g in worst[:5]],
    }


def _lockstep(planning: Planning, base: list[Outcome], every: int) -> dict[str, Any]:
    feasible = [o for o in base if not o.goal.refused and o.trajectory is not None]
    sample = feasible[::every]
    done = [execute(planning, o.goal, o.start) for o in sample]
    margins = [e.margin for e in done if math.isfinite(e.margin)]
    k = int(np.argmin(margins)) if margins else -1
    return {
        "goals": len(done),
        "statuses": dict(Counter(e.status for e in done)),
        "contacts": sum(e.contacts for e in done),
        "smallest_true_margin_mm": round(min(margins) * 1e3, 2) if margins else None,
        "tightest": done[k].tightest if k >= 0 else "",
        "tightest_goal": done[k].goal if k >= 0 else "",
        "not_succeeded": [
            {"goal": e.goal, "status": e.status, "reason": e.reason}
            for e in done
            if e.status != "succeeded"
        ],
        "final_error_mm_max": round(
            max((e.final_error for e in done if math.isfinite(e.final_error)), default=0.0) * 1e3,
            3,
        ),
    }


def _validity(planning: Planning, n: int) -> dict[str, Any]:
    """Coal's ``tightest`` and the fast check, one call per configuration and batched by
    100, timed in turns on the same 100 configurations at a time (a burst of other work
    on the machine then slows all three alike); the median over the rounds."""
    rng = np.random.default_rng(0)
    Q = rng.uniform(DEFAULT_ARM.lower_array, DEFAULT_ARM.upper_array, (n, 6))
    model, checker = planning.model, checker_for(planning.model)

    def per(fn: Any, rows: np.ndarray) -> float:
        started = time.perf_counter()
        for q in rows:
            fn(q)
        return (time.perf_counter() - started) / len(rows)

    coal, fast, batched = [], [], []
    for k in range(0, n, 100):
        rows = Q[k : k + 100]
        coal.append(per(model.tightest, rows))
        fast.append(per(checker.is_valid, rows))
        started = time.perf_counter()
        checker.is_valid_batch(rows)
        batched.append((time.perf_counter() - started) / len(rows))
    c, f, b = (float(np.median(x)) for x in (coal, fast, batched))
    return {
        "configurations": n,
        "coal_tightest_us": round(c * 1e6, 2),
        "fast_is_valid_us": round(f * 1e6, 2),
        "fast_batched_us": round(b * 1e6, 2),
        "speedup_single": round(c / f, 1),
        "speedup_batched": round(c / b, 1),
        "note": "per configuration, the median of rounds of 100 timed in turns; "
        "`manus bench validity` has the percentiles and the conservativeness",
    }
