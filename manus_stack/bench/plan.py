"""Planner speed: the thesis circle planned in-process, and the query round trip over Zenoh.

In-process: the whole :meth:`PlannerCore.plan` (validation, IK of the 19 via points,
clamped cubic spline, checks along the trajectory, preview), plus its IK and spline
steps alone. Over Zenoh, as deployed: ``manus planner`` as its own process, a client of
a loopback router that runs in this process beside the client node; the client sends the
same request many times (MessagePack both ways, the reply carrying the trajectory and its
preview). Both processes freeze their start-up heap as the services do
(:func:`manus.process.freeze_startup_heap`): without it, a full garbage collection of the
client's imports (5-15 ms here) sets the 99th percentile. ``planner_compute`` is the
planner's own time per request (``compute_ms``).
"""

from __future__ import annotations

import dataclasses
import gc
import signal
import subprocess
import sys
import time
from pathlib import Path as FilePath
from typing import Any

import numpy as np

from manus.config import DEFAULT_ARM, UNFOLDED_Q_DEG
from manus.kinematics import ik_batch
from manus.node import Node, QueryError
from manus.process import freeze_startup_heap
from manus.session import client_settings, open_session, router_settings
from manus.viapoints import load_path
from manus_stack.ports import free_port
from schemas import endpoints as ep
from schemas.planning import PlanReply, PlanRequest, ViaPointPath
from services.planner.core import PlannerCore
from services.planner.resolve import resolve_path
from services.planner.spline import PiecewisePolynomial, clamped_cubic_velocities

CIRCLE = FilePath(__file__).resolve().parents[2] / "paths" / "thesis_circle.txt"


def _stats_ms(samples: list[float]) -> dict[str, float]:
    a = np.asarray(samples) * 1e3
    return {
        "p50_ms": round(float(np.percentile(a, 50)), 4),
        "p99_ms": round(float(np.percentile(a, 99)), 4),
        "max_ms": round(float(a.max()), 4),
        "runs": len(samples),
    }


def _timed(fn: Any, runs: int) -> list[float]:
    out = []
    for _ in range(runs):
        started = time.perf_counter()
        fn()
        out.append(time.perf_counter() - started)
    return out


def _in_process(request: PlanRequest, runs: int) -> dict[str, Any]:
    core = PlannerCore()
    q0 = np.asarray(request.start, dtype=float)
    reply = core.plan(request)
    assert reply.ok, reply.error
    assert isinstance(request.motion, ViaPointPath)
    path = request.motion.path
    resolved = resolve_path(path, q0, core.config.arm)
    times = np.array([vp.time for vp in path.via_points])
    knots = np.asarray(reply.trajectory.positions if reply.trajectory else [])
    zero = np.zeros(6)

    def spline() -> None:
        v = clamped_cubic_velocities(times, knots, zero, zero)
        PiecewisePolynomial.hermite(times, knots, v)

    for _ in range(20):  # warm up
        core.plan(request)
    return {
        "full_plan": _stats_ms(_timed(lambda: core.plan(request), runs)),
        "ik_batch_only": _stats_ms(_timed(lambda: ik_batch(resolved.poses[1:], DEFAULT_ARM), runs)),
        "spline_only": _stats_ms(_timed(spline, runs)),
    }


def _over_zenoh(request: PlanRequest, runs: int) -> dict[str, Any]:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = open_session(router_settings(endpoint))
    try:
        settings = client_settings(endpoint, prefix="bench")
        command = ["planner", "--connect", endpoint, "--prefix", settings.prefix]
        planner = subprocess.Popen(
            [sys.executable, "-m", "manus_stack.cli", *command],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            with Node("bench_client", settings, liveliness=False) as client:
                freeze_startup_heap()  # as the sequencer, the planner's client, does
                try:
                    return _round_trips(client, client.keys(ep.PLAN), request, runs)
                finally:
                    gc.unfreeze()
        finally:
            planner.send_signal(signal.SIGTERM)
            try:
                planner.wait(timeout=10.0)
            except subprocess.TimeoutExpired:
                planner.kill()
                planner.wait()
    finally:
        router.close()


def _round_trips(client: Node, key: str, request: PlanRequest, runs: int) -> dict[str, Any]:
    """Round-trip times of ``runs`` queries, after the queryable answers and a warm-up."""
    deadline = time.monotonic() + 10.0
    while True:  # the queryable takes a moment to propagate through the router
        try:
            reply = client.query(key, request, PlanReply, timeout=1.0)
            break
        except QueryError:
            if time.monotonic() > deadline:
                raise
    assert reply.ok, reply.error
    for _ in range(20):
        client.query(key, request, PlanReply)
    compute: list[float] = []

    def query() -> None:
        compute.append(client.query(key, request, PlanReply).compute_ms / 1e3)

    samples = _timed(query, runs)
    return {
        **_stats_ms(samples),
        "request_bytes": len(request.encode()),
        "reply_bytes": len(reply.encode()),
        "planner_compute": _stats_ms(compute),
    }


def run(quick: bool = False) -> dict[str, Any]:
    """Figures: in-process plan of the 19-point circle and the Zenoh query round trip."""
    path = load_path(CIRCLE)
    request = PlanRequest(ViaPointPath(path=path), start=list(np.radians(UNFOLDED_Q_DEG)))
    bare = dataclasses.replace(request, preview_dt=0.0)
    runs = 300 if quick else 2000
    return {
        "path": f"{CIRCLE.name} ({len(path.via_points)} via points, cubic)",
        "in_process": _in_process(request, 200 if quick else 2000),
        "zenoh_round_trip": _over_zenoh(request, runs),
        "zenoh_round_trip_no_preview": _over_zenoh(bare, runs),
        "target": "in-process plan <= 5 ms; Zenoh round trip p99 <= 10 ms",
        "note": "the default reply carries a 60 ms Cartesian preview (421 points for this "
        "path); `no_preview` asks for preview_dt = 0, as an executing client would",
    }
