"""The guardian against a stopped or killed bridge, in lock-step and live; judged on the truth.

**Lock-step** (exact, about 0.1 s a trial): :func:`manus_stack.guardian_lockstep.bridge_fault_trial`
at 20 instants spread over the 60 ms cycle, SIGSTOP and SIGKILL, with and without the
guardian: syncs from the fault to the one whose 0x370 stopped the arm (``syncs_to_stop``,
1 = the first sync after the fault), fault -> at rest on the simulator's true motor speeds
(< 0.05 deg/s), and whether a short goal succeeds after the recovery (SIGCONT; a new bridge).

**Live** (``trials`` each, 20 by default, 2 with ``--quick``; about 8 s a trial): the
stack of ``manus up`` (router, ``manus sim --nodes 3``, bridge, guardian, planner,
controller, sequencer) with this process as the bus's third node, listening. Each trial
runs a task (home pose, then the thesis square) through the sequencer, waits until the
arm moves, then sends the
bridge SIGSTOP or SIGKILL at a seeded instant. From the bus (this node's receive clock):
``syncs_to_stop`` (syncs after the fault up to the first one answered by a 0x370) and
``reaction_on_wire_ms`` (that 0x370's arrival minus its sync's minus the 12 ms deadline: the
guardian's reaction plus the simulator's forwarding, on the wire as the arm sees it). From
``sim/truth`` (the simulator's true joint speeds): fault -> at rest. Recovery: SIGCONT
after 0.5 s, or a new bridge on the same adapter; ``resumed`` counts trials where the arm
moved again by itself (> 0.35 deg in the next second; the new bridge's start-up pulses of
motors 4-6 are 0.3 deg at most). The guardian's own ``stats:`` line gives its CPU time
per sync seen and its reaction (deadline -> ``bus.send`` returned).
"""

from __future__ import annotations

import json
import math
import os
import random
import signal
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import numpy as np

from manus.node import Node
from manus.protocol import FrameId
from manus.session import client_settings
from manus_stack.guardian_lockstep import bridge_fault_trial
from manus_stack.ports import free_port
from manus_stack.up import LocalStack, StackOptions
from schemas import endpoints as ep
from schemas.sequencing import SubmitReply, Task, TaskEvent, TaskStep
from schemas.state import BridgeState, SimTruth
from services.sequencer.taskfile import task_from_args

ROOT = Path(__file__).resolve().parents[2]
SQUARE = ROOT / "paths" / "thesis_square.txt"
DEADLINE_MS = 12.0
REST_RAD_S = math.radians(0.05)
"""At rest: every true joint speed below this [rad/s]."""


def _stats(values: list[float]) -> dict[str, float]:
    if not values:
        return {"n": 0}
    a = np.asarray(values, dtype=float)
    return {
        "n": len(values),
        "p50": round(float(np.percentile(a, 50)), 2),
        "max": round(float(a.max()), 2),
    }


def lockstep_figures(quick: bool) -> dict[str, Any]:
    """The lock-step trials (see the module docstring)."""
    offsets = [0.5 + 3.0 * i for i in range(5 if quick else 20)]
    out: dict[str, Any] = {}
    for fault in ("stop", "kill"):
        trials = [bridge_fault_trial(fault, off) for off in offsets]
        bare = bridge_fault_trial(fault, 30.0, guardian=False)
        out[fault] = {
            "trials": len(trials),
            "syncs_to_stop": sorted({t.syncs_to_stop or 0 for t in trials}),
            "rest_ms": _stats([t.rest_ms if t.rest_ms is not None else math.inf for t in trials]),
            "resumed": sum(t.resumed_moving for t in trials),
            "new_goal_succeeded": sum(t.new_goal == "succeeded" for t in trials),
            "without_guardian_rest_ms": bare.rest_ms,
        }
    return out


@dataclass
class Listener:
    """This process as a node on the simulator's bus: every frame, with its receive time."""

    bus: can.BusABC
    frames: list[tuple[int, int]] = field(default_factory=list)  # (time.time_ns, id)
    lock: threading.Lock = field(default_factory=threading.Lock)
    stop: threading.Event = field(default_factory=threading.Event)

    def run(self) -> None:
        while not self.stop.is_set():
            msg = self.bus.recv(timeout=0.05)
            if msg is not None:
                with self.lock:
                    self.frames.append((time.time_ns(), int(msg.arbitration_id)))

    def since(self, t_ns: int) -> list[tuple[int, int]]:
        with self.lock:
            return [f for f in self.frames if f[0] >= t_ns]


@dataclass
class Watcher:
    """The stack as its truth and the bridge's state show it (wall-clock receive times)."""

    truth: list[tuple[int, SimTruth]] = field(default_factory=list)
    bridge: list[BridgeState] = field(default_factory=list)
    events: list[TaskEvent] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def on_truth(self, msg: SimTruth, rx_ns: int) -> None:
        with self.lock:
            self.truth.append((rx_ns, msg))

    def on_bridge(self, msg: BridgeState, rx_ns: int) -> None:
        with self.lock:
            self.bridge.append(msg)

    def on_event(self, msg: TaskEvent, rx_ns: int) -> None:
        with self.lock:
            self.events.append(msg)

    def speed(self) -> float:
        """Largest true joint speed of the newest truth [rad/s]."""
        with self.lock:
            return max(abs(v) for v in self.truth[-1][1].qd_true) if self.truth else 0.0

    def rest_after(self, t_ns: int) -> float | None:
        """Time from ``t_ns`` to the first truth from which on every one is at rest [ms]."""
        with self.lock:
            after = [(t, max(abs(v) for v in m.qd_true)) for t, m in self.truth if t >= t_ns]
        moving = [t for t, v in after if v >= REST_RAD_S]
        if not after or (moving and moving[-1] == after[-1][0]):
            return None
        rest = next(t for t, v in after if t > (moving[-1] if moving else 0))
        return (rest - t_ns) / 1e6

    def moved_since(self, t_ns: int) -> float:
        """Largest true joint displacement since ``t_ns`` [rad]."""
        with self.lock:
            q = [np.asarray(m.q_true) for t, m in self.truth if t >= t_ns]
        return float(np.max(np.abs(np.asarray(q) - q[0]))) if len(q) > 1 else 0.0

    def phase(self) -> str:
        with self.lock:
            return self.bridge[-1].phase if self.bridge else ""


def _wait(what: str, cond: Callable[[], bool], timeout: float) -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise TimeoutError(f"{what}: not within {timeout:g} s")
        time.sleep(0.02)


def stop_on_wire(frames: list[tuple[int, int]]) -> tuple[int | None, float | None]:
    """(syncs up to the first one answered by a 0x370, that 0x370's delay after its sync
    minus the deadline [ms]) from the frames after a fault."""
    syncs = 0
    sync_t: int | None = None
    for t, fid in frames:
        if fid == FrameId.SYNC:
            syncs += 1
            sync_t = t
        elif fid == FrameId.STOP and sync_t is not None and t - sync_t < 20_000_000:
            return syncs, (t - sync_t) / 1e6 - DEADLINE_MS
    return None, None


def live_figures(trials: int, seed: int = 0) -> dict[str, Any]:
    """The live trials (see the module docstring)."""
    rng = random.Random(seed)
    run_dir = Path(tempfile.mkdtemp(prefix="manus-bench-guardian-"))
    (run_dir / "sim.json").write_text(json.dumps({"start_pose": "unfolded"}))
    options = StackOptions(
        run_dir=run_dir,
        endpoint=f"tcp/127.0.0.1:{free_port()}",
        prefix="benchguardian",
        record=False,
        sim_args=["--config", str(run_dir / "sim.json"), "--nodes", "3"],
    )
    stack = LocalStack(options)
    results: dict[str, Any] = {}
    listener: Listener | None = None
    try:
        stack.start(timeout=60.0)
        device2 = Path(f"{options.device_file}.2").read_text()
        bus = can.Bus(interface="slcan", channel=device2, bitrate=250_000, sleep_after_open=0)
        listener = Listener(bus)
        threading.Thread(target=listener.run, daemon=True).start()
        watch = Watcher()
        settings = client_settings(options.endpoint, prefix=options.prefix)
        with Node("bench-guardian", settings, liveliness=False) as node:
            node.subscribe(node.keys(ep.SIM_TRUTH), SimTruth, watch.on_truth, locked=False)
            node.subscribe(node.keys(ep.BRIDGE_STATE), BridgeState, watch.on_bridge, locked=False)
            node.subscribe(node.keys(ep.EVENTS), TaskEvent, watch.on_event, locked=False)
            _wait("the bridge running", lambda: watch.phase() == "running", 30.0)
            for fault in ("stop", "kill"):
                results[fault] = _live_trials(stack, node, watch, listener, fault, trials, rng)
    finally:
        if listener is not None:
            listener.stop.set()
            time.sleep(0.1)
            listener.bus.shutdown()
        stack.stop(grace=5.0)
    results["guardian_process"] = _guardian_stats(run_dir / "logs" / "guardian.log")
    return results


TASK = Task(
    steps=[
        TaskStep(kind="pose", pose="home", duration=2.0),
        *task_from_args([str(SQUARE)]).steps,
    ],
    name="guardian bench",
)
"""Back home (the last trial stopped the arm anywhere), then the thesis square."""


def _submit(node: Node, task: Task) -> SubmitReply:
    return node.query(node.keys(ep.SUBMIT), task, SubmitReply, timeout=30.0)


def _start_moving(node: Node, watch: Watcher, attempts: int = 3) -> None:
    """Submit the task until the arm moves (a busy machine may fail a task: retried)."""
    failures: list[str] = []
    for _ in range(attempts):
        end = time.monotonic() + 30.0
        while not (reply := _submit(node, TASK)).accepted:
            if time.monotonic() > end:
                raise TimeoutError(f"the sequencer refused the task for 30 s: {reply.errors}")
            time.sleep(0.2)
        try:
            _wait("the arm moving", lambda: watch.speed() > math.radians(2.0), 20.0)
            time.sleep(1.0)  # into the path: then at a moment it moves (not between steps)
            _wait("the arm moving on", lambda: watch.speed() > math.radians(2.0), 5.0)
            return
        except TimeoutError as exc:
            failures.append(str(exc))
            with watch.lock:
                failures += [e.reason for e in watch.events[-3:] if e.event == "failed"]
    raise TimeoutError(f"the arm did not move after {attempts} tasks: {failures}")


def _live_trials(
    stack: LocalStack,
    node: Node,
    watch: Watcher,
    listener: Listener,
    fault: str,
    trials: int,
    rng: random.Random,
) -> dict[str, Any]:
    syncs_to_stop: list[int] = []
    reaction: list[float] = []
    rest: list[float] = []
    speed: list[float] = []
    resumed = 0
    for _ in range(trials):
        _start_moving(node, watch)
        time.sleep(rng.uniform(0.0, 0.06))
        speed.append(math.degrees(watch.speed()))
        bridge = next(c for c in stack.children if c.name == "bridge")
        t_fault = time.time_ns()
        os.kill(bridge.proc.pid, signal.SIGSTOP if fault == "stop" else signal.SIGKILL)
        time.sleep(1.0)
        n, late = stop_on_wire(listener.since(t_fault))
        syncs_to_stop.append(n or 0)
        if late is not None:
            reaction.append(late)
        r = watch.rest_after(t_fault)
        rest.append(r if r is not None else math.inf)
        if fault == "stop":
            os.kill(bridge.proc.pid, signal.SIGCONT)
        else:
            stack.respawn(bridge)
        t_back = time.time_ns()
        _wait("the bridge running again", lambda: watch.phase() == "running", 30.0)
        time.sleep(1.0)
        resumed += watch.moved_since(t_back) > math.radians(0.35)
        print(
            f"guardian bench: {fault} trial: {syncs_to_stop[-1]} sync(s), rest {rest[-1]} ms",
            file=sys.stderr,
            flush=True,
        )
    return {
        "trials": trials,
        "syncs_to_stop": sorted(set(syncs_to_stop)),
        "stop_at_first_sync": sum(n == 1 for n in syncs_to_stop),
        "reaction_on_wire_ms": _stats(reaction),
        "speed_at_fault_deg_s": _stats(speed),
        "rest_ms": _stats(rest),
        "resumed": resumed,
    }


def _guardian_stats(log: Path) -> dict[str, Any]:
    lines = [x for x in log.read_text(errors="replace").splitlines() if x.startswith("stats: ")]
    if not lines:
        return {"error": f"no stats line in {log}"}
    stats: dict[str, Any] = json.loads(lines[-1].removeprefix("stats: "))
    syncs = max(1, int(stats.get("syncs", 0)))
    stats["cpu_ms_per_sync"] = round(float(stats.get("cpu_ms", 0.0)) / syncs, 3)
    return stats


def run(quick: bool = False) -> dict[str, Any]:
    """Lock-step and live figures (see the module docstring)."""
    return {
        "lockstep": lockstep_figures(quick),
        "live": live_figures(2 if quick else 20),
        "load_avg": [round(x, 2) for x in os.getloadavg()],
    }
