"""Fuzzing figures: inputs tried per endpoint and crashes (target 0), core level and live.

**Core level** (:func:`manus_stack.fuzz.run_fuzz`): seeds 0-4 (``--quick``: seed 0), 50
payloads per endpoint of ``channel_types()`` (10) through decode and the lock-step cores,
5000 random CAN frames into the bridge (1000), then the documented recovery, a fold out
and the thesis square.

**Live** (:func:`manus_stack.fuzz_live.fuzz_live`): the stack of ``manus up`` (no recorder),
20 bad payloads per key and per queryable (5), then every process must be alive, every
service's count (``health/<service>``, what ``manus status`` shows) must equal what it
was sent on each key it listens to, and the square must run.
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path
from typing import Any

from manus.node import Node
from manus.session import client_settings
from manus_stack.fuzz import run_fuzz
from manus_stack.fuzz_live import fuzz_live
from manus_stack.ports import free_port
from manus_stack.status import node_health
from manus_stack.up import LocalStack, StackOptions
from schemas import endpoints as ep
from schemas.sequencing import SubmitReply, TaskEvent
from services.sequencer.taskfile import task_from_args

SQUARE = Path(__file__).resolve().parents[2] / "paths" / "thesis_square.txt"


def core_figures(quick: bool) -> dict[str, Any]:
    """Core-level runs, one per seed."""
    runs: list[dict[str, Any]] = []
    crashes = 0
    for seed in range(1 if quick else 5):
        started = time.perf_counter()
        r = run_fuzz(seed, per_endpoint=10 if quick else 50, frames=1000 if quick else 5000)
        runs.append({
            "seed": seed,
            "endpoints": len(r.inputs),
            "inputs_per_endpoint": max(r.inputs.values()),
            "decoded": sum(r.decoded.values()),
            "refused_by_cores": r.refused,
            "can_frames": r.can_frames,
            "crashes": r.crashes,
            "task_after": r.task_after,
            "seconds": round(time.perf_counter() - started, 1),
        })  # fmt: skip
        crashes += len(r.crashes)
    return {"runs": runs, "crashes": crashes}


def live_figures(per_endpoint: int) -> dict[str, Any]:
    """One live run against the stack."""
    run_dir = Path(tempfile.mkdtemp(prefix="manus-bench-fuzz-"))
    (run_dir / "sim.json").write_text(json.dumps({"start_pose": "unfolded"}))
    options = StackOptions(
        run_dir=run_dir,
        endpoint=f"tcp/127.0.0.1:{free_port()}",
        prefix="benchfuzz",
        record=False,
        sim_args=["--config", str(run_dir / "sim.json")],
    )
    with LocalStack(options) as stack:
        stack.start(timeout=60.0)
        settings = client_settings(options.endpoint, prefix=options.prefix)
        with Node("bench-fuzz", settings, liveliness=False) as node:
            done = fuzz_live(node, seed=0, per_endpoint=per_endpoint)
            time.sleep(1.0)
            health = node_health(node)
            lost = [
                f"{service} {key}: {n} of {done.sent[key]}"
                for service, h in health.items()
                for key, n in h["by_key"].items()
                if n != done.sent[key]
            ]
            events: list[TaskEvent] = []
            node.subscribe(node.keys(ep.EVENTS), TaskEvent, lambda e, t: events.append(e))
            reply = node.query(
                node.keys(ep.SUBMIT), task_from_args([str(SQUARE)]), SubmitReply,
                timeout=30.0,
            )  # fmt: skip
            end = time.monotonic() + 60.0
            while reply.accepted and time.monotonic() < end:
                final = [e for e in events if e.event in ("succeeded", "failed", "cancelled")]
                if final:
                    break
                time.sleep(0.1)
            if not reply.accepted:
                task = f"refused: {reply.errors}"
            else:
                task = f"{final[-1].event} {final[-1].reason}".strip() if final else "no end"
        dead = [c.name for c in stack.exited()]
    return {
        "endpoints": len(done.sent),
        "payloads_per_endpoint": per_endpoint,
        "queries_refused": sum(done.refused.values()),
        "counted_by_service": {s: h["bad_payloads"] for s, h in health.items()},
        "counts_lost": lost,
        "processes_died": dead,
        "task_after": task,
    }


def run(quick: bool = False) -> dict[str, Any]:
    """Core-level and live fuzz figures."""
    return {"core": core_figures(quick), "live": live_figures(5 if quick else 20)}
