"""Helpers of the live fault tests: the whole stack (``LocalStack``) plus a watcher.

The watcher is a Zenoh node of the test that records, each with its wall-clock receive
time [ns], the bridge's raw ``can/tx`` frames (stamped by the bridge with their send
time, the same clock on one host), the simulator's ``sim/truth``, the sequencer's task
events and every liveliness change. Fault timings are read from these records.
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from manus.node import Node
from manus.protocol import FrameId, decode_move
from manus.session import client_settings
from manus_stack.up import Child, LocalStack, StackOptions
from schemas import endpoints as ep
from schemas.guardian import GuardianReport
from schemas.sequencing import SubmitReply, Task, TaskEvent
from schemas.state import BridgeState, CanFrame, SimTruth

ROOT = Path(__file__).resolve().parent.parent
SQUARE = ROOT / "paths" / "thesis_square.txt"
LEASE_MS = 400
"""Zenoh lease of every process of the fault tests [ms]: a hung process's liveliness
token vanishes within about this long."""


@dataclass
class Watch:
    """What the test's node has seen (append-only lists, guarded by ``lock``)."""

    lock: threading.Lock = field(default_factory=threading.Lock)
    tx: list[CanFrame] = field(default_factory=list)
    truth: list[SimTruth] = field(default_factory=list)
    events: list[TaskEvent] = field(default_factory=list)
    bridge: list[BridgeState] = field(default_factory=list)
    alive: list[tuple[int, str, bool]] = field(default_factory=list)
    guardian: list[GuardianReport] = field(default_factory=list)

    def joint_moves(self, since_ns: int = 0) -> list[tuple[int, bool]]:
        """(send time [ns], all zero) of every 0x374 the bridge sent from ``since_ns``."""
        with self.lock:
            frames = list(self.tx)
        return [
            (f.stamp_ns, decode_move(f.id, f.data).is_zero)
            for f in frames
            if f.id == FrameId.JOINT and f.stamp_ns >= since_ns
        ]

    def sent_ids(self, since_ns: int = 0) -> list[tuple[int, int]]:
        """(send time [ns], CAN id) of every frame the bridge sent from ``since_ns``."""
        with self.lock:
            return [(f.stamp_ns, f.id) for f in self.tx if f.stamp_ns >= since_ns]

    def truths(self) -> list[SimTruth]:
        """Every truth the simulator published so far (at least one)."""
        with self.lock:
            assert self.truth, "no truth from the simulator"
            return list(self.truth)

    def event_names(self) -> list[str]:
        with self.lock:
            return [e.event for e in self.events if e.event != "step_progress"]

    def gone(self, service: str, since_ns: int) -> int | None:
        """When ``service``'s token vanished after ``since_ns`` [ns] (None: not yet)."""
        with self.lock:
            for t, name, up in self.alive:
                if name == service and not up and t >= since_ns:
                    return t
        return None


class FaultStack:
    """``LocalStack`` (simulator starting unfolded, no recorder, the guardian beside the
    bridge) + a watching node."""

    def __init__(self, run_dir: Path, endpoint: str, prefix: str) -> None:
        config = run_dir / "sim.json"
        run_dir.mkdir(parents=True, exist_ok=True)
        config.write_text(json.dumps({"start_pose": "unfolded"}))
        self.options = StackOptions(
            run_dir=run_dir,
            endpoint=endpoint,
            prefix=prefix,
            record=False,
            sim_args=["--config", str(config)],
        )
        self.stack = LocalStack(self.options)
        self.watch = Watch()
        self.node: Node | None = None

    def start(self) -> None:
        self.stack.start(timeout=60.0)
        settings = client_settings(self.options.endpoint, prefix=self.options.prefix)
        node = self.node = Node("faults-test", settings, liveliness=False)
        keys = node.keys
        w = self.watch

        def keep(target: list) -> object:  # type: ignore[type-arg]
            def add(msg: object, rx: int) -> None:
                with w.lock:
                    target.append(msg)

            return add

        node.subscribe(keys(ep.CAN_TX), CanFrame, keep(w.tx), locked=False)  # type: ignore[arg-type]
        node.subscribe(keys(ep.SIM_TRUTH), SimTruth, keep(w.truth), locked=False)  # type: ignore[arg-type]
        node.subscribe(keys("sequencer/events"), TaskEvent, keep(w.events), locked=False)  # type: ignore[arg-type]
        node.subscribe(keys(ep.BRIDGE_STATE), BridgeState, keep(w.bridge), locked=False)  # type: ignore[arg-type]
        node.subscribe(keys(ep.GUARDIAN_REPORT), GuardianReport, keep(w.guardian), locked=False)  # type: ignore[arg-type]

        def on_alive(name: str, up: bool) -> None:
            with w.lock:
                w.alive.append((time.time_ns(), name, up))

        node.watch_liveliness(on_alive)

        def running() -> bool:
            with w.lock:
                return bool(w.bridge) and w.bridge[-1].phase == "running"

        self.wait("the bridge in phase running", running, 30.0)

    def child(self, name: str) -> Child:
        return next(c for c in self.stack.children if c.name == name)

    def submit(self, task: Task) -> SubmitReply:
        assert self.node is not None
        return self.node.query(self.node.keys("sequencer/submit"), task, SubmitReply, timeout=30.0)

    def wait(self, what: str, cond: object, timeout: float) -> None:
        """Poll ``cond()`` every 20 ms until true; AssertionError naming ``what`` after
        ``timeout`` [s]."""
        end = time.monotonic() + timeout
        while not cond():  # type: ignore[operator]
            if time.monotonic() > end:
                raise AssertionError(f"{what}: not within {timeout:g} s")
            time.sleep(0.02)

    def wait_moving(self, timeout: float = 20.0) -> None:
        """Until the bridge has sent non-zero 0x374 frames for a second."""
        start = time.time_ns()

        def moving() -> bool:
            moves = [t for t, zero in self.watch.joint_moves(start) if not zero]
            return bool(moves) and moves[-1] - moves[0] > 1_000_000_000

        self.wait("the arm moving", moving, timeout)

    def close(self) -> None:
        if self.node is not None:
            self.node.close()
            self.node = None
        self.stack.stop(grace=5.0)

    def __enter__(self) -> FaultStack:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
