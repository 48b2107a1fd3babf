"""The goal set's plans through the planner service (``manus bench reach``): ``manus
planner`` in its own process behind a loopback router, asked over Zenoh with the same
plan requests the in-process figures time, as a supervisor's sequencer asks it.

Each request is sent :data:`ROUNDS` times; the round trip is timed at the client (the
request and the reply encoded, sent, decoded), and the reply must equal the in-process
core's (the planner is deterministic: same request, same reply).
"""

from __future__ import annotations

import gc
import signal
import subprocess
import sys
import time
from typing import Any

from manus.node import Node, QueryError
from manus.process import freeze_startup_heap
from manus.session import client_settings, open_session, router_settings
from manus_stack.bench.reach_run import Outcome, Planning, stats_ms
from manus_stack.ports import free_port
from schemas import endpoints as ep
from schemas.planning import PlanReply

ROUNDS = 3
"""Times each request is sent."""


def round_trips(planning: Planning, base: list[Outcome], rounds: int = ROUNDS) -> dict[str, Any]:
    """Figures of the plans of ``base`` (each goal from its start, seed 1) over Zenoh."""
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
                freeze_startup_heap()
                try:
                    return _ask(client, planning, base, rounds)
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


def _ask(client: Node, planning: Planning, base: list[Outcome], rounds: int) -> dict[str, Any]:
    key = client.keys(ep.PLAN)
    requests = [planning.request(o.goal, o.start) for o in base]
    deadline = time.monotonic() + 30.0
    while True:  # the queryable takes a moment to appear (and to build its fast check)
        try:
            client.query(key, requests[0], PlanReply, timeout=5.0)
            break
        except QueryError:
            if time.monotonic() > deadline:
                raise
    feasible: list[float] = []
    infeasible: list[float] = []
    compute: list[float] = []
    differ: list[str] = []
    for outcome, request in zip(base, requests, strict=True):
        local = planning.core.plan(request)
        for _ in range(rounds):
            started = time.perf_counter()
            reply = client.query(key, request, PlanReply, timeout=10.0)
            elapsed = time.perf_counter() - started
            (infeasible if outcome.goal.refused else feasible).append(elapsed)
            compute.append(reply.compute_ms / 1e3)
            if reply.ok != local.ok or reply.trajectory != local.trajectory:
                differ.append(outcome.goal.id)
    return {
        "feasible": stats_ms(feasible),
        "infeasible": stats_ms(infeasible),
        "planner_compute": stats_ms(compute),
        "replies_unlike_in_process": sorted(set(differ)),
    }
