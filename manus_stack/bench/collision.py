"""Collision checking speed: whole trajectories, distance queries, the controller's guard.

- ``trajectory_check``: the thesis circle's whole trajectory (planned without a scene)
  swept through the default wheelchair scene (:func:`services.planner.collisions.
  check_collisions`, the fast check first), in-process, and in turns with it the exact
  sweep alone (:func:`manus.sweep.exact_sweep`, Coal at every configuration it checks:
  the check before the fast one); and the whole plan with and without the check.
- ``zenoh_round_trip``: ``manus planner`` (checking against the default scene) asked
  over a loopback router, as :mod:`manus_stack.bench.plan` does.
- ``distance_queries``: body-object distances per second through
  :func:`pinocchio.computeDistances` (every pair of the model in one call), against a
  naive loop that places each pair and calls :func:`coal.distance` from Python.
- ``guard``: :meth:`services.controller.guard.Guard.filter` per 60 ms cycle along the
  circle at its planned speeds (most cycles are proven clear without a distance), and
  with every cycle forced to compute (the worst case, near an obstacle).
"""

from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path as FilePath
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from manus.collision import CollisionModel
from manus.config import DEFAULT_ARM, UNFOLDED_Q_DEG
from manus.joint_map import dh_increments_to_encoder
from manus.quantize import COUNT_RAD_S, step_rates
from manus.scene import default_scene
from manus.sweep import exact_sweep, sweep
from manus.viapoints import load_path
from manus_stack.bench.plan import _over_zenoh, _stats_ms, _timed
from schemas.planning import PlanRequest, ViaPointPath
from services.controller.guard import Guard
from services.planner.collisions import check_collisions
from services.planner.config import PlannerConfig
from services.planner.core import PlannerCore
from services.planner.labels import KnotLabels
from services.planner.spline import PiecewisePolynomial

CIRCLE = FilePath(__file__).resolve().parents[2] / "paths" / "thesis_circle.txt"


def _circle_curve(request: PlanRequest) -> PiecewisePolynomial:
    reply = PlannerCore(PlannerConfig(scene="none")).plan(request)
    assert reply.trajectory is not None, reply.error
    t = reply.trajectory
    return PiecewisePolynomial.hermite(
        np.array(t.times), np.array(t.positions), np.array(t.velocities)
    )


def _trajectory(request: PlanRequest, runs: int) -> dict[str, Any]:
    model = CollisionModel(default_scene(), DEFAULT_ARM)
    curve = _circle_curve(request)
    ex = curve.extremes(1)
    swept = sweep(model, curve.times, np.maximum(-ex.low, ex.high), curve.evaluate)
    peaks = np.maximum(-ex.low, ex.high)
    exact = exact_sweep(model, curve.times, peaks, curve.evaluate)
    assert isinstance(request.motion, ViaPointPath)
    labels = KnotLabels.of_path(request.motion.path)
    # The check as the planner runs it (fast first) and the exact sweep alone, in turns.
    fast_s: list[float] = []
    exact_s: list[float] = []
    for _ in range(runs):
        fast_s += _timed(lambda: check_collisions(model, curve, labels), 1)
        exact_s += _timed(lambda: exact_sweep(model, curve.times, peaks, curve.evaluate), 1)
    checked = _stats_ms(fast_s)
    with_check, without = PlannerCore(), PlannerCore(PlannerConfig(scene="none"))
    return {
        "check_only": checked,
        "exact_sweep_only": {
            **_stats_ms(exact_s),
            "configurations_checked": exact.checked,
            "smallest_clearance": exact.worst.describe(),
        },
        "speedup_p50": round(float(np.percentile(exact_s, 50) / np.percentile(fast_s, 50)), 1),
        "configurations_checked": swept.checked,
        "grid_samples": swept.samples,
        "smallest_clearance": swept.worst.describe(),
        "plan_with_check": _stats_ms(_timed(lambda: with_check.plan(request), runs)),
        "plan_without_check": _stats_ms(_timed(lambda: without.plan(request), runs)),
    }


def _distance_queries(seconds: float) -> dict[str, Any]:
    model = CollisionModel(default_scene(), DEFAULT_ARM)
    rng = np.random.default_rng(0)
    qs = np.radians(UNFOLDED_Q_DEG) + rng.uniform(-0.5, 0.5, (200, 6))
    pairs = len(model.checks)
    gm, gd = model.geom, model.geom_data

    def batched() -> None:
        for q in qs:
            pin.computeDistances(model.model, model.data, gm, gd, q)

    def naive() -> None:
        request = coal.DistanceRequest()
        for q in qs:
            pin.forwardKinematics(model.model, model.data, q)
            pin.updateGeometryPlacements(model.model, model.data, gm, gd)
            for cp in gm.collisionPairs:
                a, b = gm.geometryObjects[cp.first], gm.geometryObjects[cp.second]
                ma, mb = gd.oMg[cp.first], gd.oMg[cp.second]
                coal.distance(
                    a.geometry,
                    coal.Transform3s(ma.rotation, ma.translation),
                    b.geometry,
                    coal.Transform3s(mb.rotation, mb.translation),
                    request,
                    coal.DistanceResult(),
                )

    def rate(fn: Any) -> float:
        done, started = 0, time.perf_counter()
        while time.perf_counter() - started < seconds:
            fn()
            done += len(qs) * pairs
        return done / (time.perf_counter() - started)

    ours, loop = rate(batched), rate(naive)
    return {
        "pairs_per_configuration": pairs,
        "per_second": round(ours),
        "naive_loop_per_second": round(loop),
        "ratio": round(ours / loop, 1),
    }


def _guard(request: PlanRequest) -> dict[str, Any]:
    model = CollisionModel(default_scene(), DEFAULT_ARM, opening=0.0)
    curve = _circle_curve(request)
    ts = np.arange(0.0, curve.duration, 0.06)
    Q, V = curve.evaluate(ts), curve.evaluate(ts, order=1)
    counts = [np.round(dh_increments_to_encoder(v) / COUNT_RAD_S).astype(np.int64) for v in V]
    guard = Guard(model)

    def cycles(force: bool) -> list[float]:
        out = []
        for k in range(1, len(ts)):
            if force:
                guard.advance.forget()
            started = time.perf_counter()
            guard.filter(list(Q[k]), step_rates(counts[k - 1].tolist()), counts[k], 0.0)
            out.append(time.perf_counter() - started)
        return out

    cycles(False)  # warm up
    before = guard.computed
    normal = cycles(False)
    computed = guard.computed - before
    return {
        "per_cycle": _stats_ms(normal),
        "configurations_computed": computed,
        "cycles": len(normal),
        "every_cycle_computing": _stats_ms(cycles(True)),
    }


def run(quick: bool = False) -> dict[str, Any]:
    """Figures of the trajectory check, distance queries and the guard (see the module)."""
    path = load_path(CIRCLE)
    request = PlanRequest(
        ViaPointPath(path=path), start=list(np.radians(UNFOLDED_Q_DEG)), preview_dt=0.0
    )
    runs = 50 if quick else 500
    return {
        "path": f"{CIRCLE.name} ({len(path.via_points)} via points, cubic, "
        f"{math.ceil(path.via_points[-1].time)} s)",
        "scene": str(default_scene().source),
        "trajectory_check": _trajectory(request, runs),
        "zenoh_round_trip_no_preview": _over_zenoh(
            dataclasses.replace(request, preview_dt=0.0), 200 if quick else 2000
        ),
        "distance_queries": _distance_queries(0.5 if quick else 3.0),
        "guard": _guard(request),
        "target": "trajectory check p99 <= 10 ms; plan + check round trip p99 <= 10 ms; "
        "guard p99 <= 1 ms per cycle",
    }
