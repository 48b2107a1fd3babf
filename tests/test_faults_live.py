"""Fault tests on one host: the real processes of ``manus up``, faults made by the test.

Each test brings up the stack (router, simulator starting unfolded, bridge, planner,
controller, sequencer; Zenoh lease ``LEASE_MS`` for every process), starts the thesis
square through the sequencer, makes one fault on a process it started (by pid) and reads
the outcome from the bridge's raw ``can/tx`` frames, the simulator's truth and the
sequencer's events. Stop times are printed (``-s``) as figures, not asserted tightly:
what is asserted is the rule (zeros, nothing moving on a stale command, the task failed).
"""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from schemas.keys import channel_types
from services.sequencer.taskfile import task_from_args
from tests.conftest import free_port
from tests.fault_stack import LEASE_MS, SQUARE, FaultStack

pytestmark = pytest.mark.slow
CYCLE_MS = 60.0


@pytest.fixture
def stack(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[FaultStack]:
    monkeypatch.setenv("MANUS_ZENOH_LEASE_MS", str(LEASE_MS))
    fs = FaultStack(tmp_path / "run", f"tcp/127.0.0.1:{free_port()}", "faults")
    try:
        fs.start()
        yield fs
    finally:
        fs.close()


def _start_square(fs: FaultStack) -> None:
    end = time.monotonic() + 15.0
    while not (reply := fs.submit(task_from_args([str(SQUARE)]))).accepted:
        assert time.monotonic() < end, reply.errors  # right after start-up: no state yet
        time.sleep(0.2)
    fs.wait_moving()


def _first_zero_after(fs: FaultStack, t_ns: int) -> float:
    """Time [ms] from ``t_ns`` to the first all-zero 0x374 sent after it."""
    fs.wait("a zero 0x374", lambda: any(z for _, z in fs.watch.joint_moves(t_ns)), 5.0)
    first = next(t for t, z in fs.watch.joint_moves(t_ns) if z)
    return (first - t_ns) / 1e6


def _report(name: str, **figures: float) -> None:
    print(f"FAULT {name}: " + ", ".join(f"{k} {v:.0f} ms" for k, v in figures.items()))


def test_controller_killed_mid_path_zeros_within_two_cycles(stack: FaultStack) -> None:
    _start_square(stack)
    controller = stack.child("controller")
    t_kill = time.time_ns()
    os.kill(controller.proc.pid, signal.SIGKILL)
    controller.proc.wait(timeout=5.0)
    stop_ms = _first_zero_after(stack, t_kill)
    _report("controller SIGKILL", first_zero=stop_ms)
    assert stop_ms <= 2 * CYCLE_MS + 20.0  # the next sync, at most a cycle and a bit later
    time.sleep(1.0)
    assert all(z for t, z in stack.watch.joint_moves(t_kill) if (t - t_kill) / 1e6 > stop_ms)
    stack.wait("task failed", lambda: "failed" in stack.watch.event_names(), 5.0)
    failed = [e for e in stack.watch.events if e.event == "failed"][-1]
    assert "controller" in failed.reason


def test_controller_hangs_liveliness_and_freshness_stop_the_arm(stack: FaultStack) -> None:
    _start_square(stack)
    controller = stack.child("controller")
    t_stop = time.time_ns()
    os.kill(controller.proc.pid, signal.SIGSTOP)
    try:
        stop_ms = _first_zero_after(stack, t_stop)
        stack.wait("controller token gone", lambda: stack.watch.gone("controller", t_stop), 5.0)
        gone = stack.watch.gone("controller", t_stop)
        assert gone is not None
        gone_ms = (gone - t_stop) / 1e6
        stack.wait("task failed", lambda: "failed" in stack.watch.event_names(), 5.0)
        _report("controller SIGSTOP", first_zero=stop_ms, liveliness_lost=gone_ms)
        assert stop_ms <= 2 * CYCLE_MS + 20.0
        assert gone_ms <= 4 * LEASE_MS
        failed = [e for e in stack.watch.events if e.event == "failed"][-1]
        assert "controller is gone" in failed.reason
        assert all(z for t, z in stack.watch.joint_moves(t_stop) if (t - t_stop) / 1e6 > stop_ms)
    finally:
        os.kill(controller.proc.pid, signal.SIGCONT)
    # woken up, it finds a gap of seconds in the joint states: its goal aborts, no motion
    time.sleep(1.0)
    late = time.time_ns() - 500_000_000
    assert all(z for _, z in stack.watch.joint_moves(late))


def test_bridge_stopped_sends_zeros_then_stop(stack: FaultStack) -> None:
    _start_square(stack)
    bridge = stack.child("bridge")
    t_term = time.time_ns()
    os.kill(bridge.proc.pid, signal.SIGTERM)
    assert bridge.proc.wait(timeout=10.0) == 0
    time.sleep(0.3)  # the last frames' publications
    ids = [(t, i) for t, i in stack.watch.sent_ids(t_term) if i in (0x374, 0x370)]
    first_stop = next(k for k, (_, i) in enumerate(ids) if i == 0x370)
    zeros = [z for t, z in stack.watch.joint_moves(t_term)]
    assert zeros and zeros[-1], "the last 0x374 before the stop is zeros"
    stop_ms = (ids[first_stop][0] - t_term) / 1e6
    _report("bridge SIGTERM", stop_0x370=stop_ms)
    # the simulator's truth: at rest after the stop
    time.sleep(0.5)
    with stack.watch.lock:
        q = [np.asarray(tr.q_true) for tr in stack.watch.truth[-4:]]
    assert all(np.allclose(q[0], qi, atol=1e-6) for qi in q)


def test_bridge_killed_outright_the_arm_latches_until_a_new_bridge_stops_it(
    stack: FaultStack,
) -> None:
    """SIGKILL leaves no chance to send anything: the arm repeats its last command
    (docs/protocol.md, The 60 ms cycle: a latched command acts until the next one). The
    mitigation shown: a bridge started again (compose's ``restart: on-failure``) sends 0x370
    at its first sync."""
    _start_square(stack)
    bridge = stack.child("bridge")
    os.kill(bridge.proc.pid, signal.SIGKILL)
    bridge.proc.wait(timeout=5.0)
    t_kill = time.time_ns()
    time.sleep(1.0)
    with stack.watch.lock:
        after = [tr for tr in stack.watch.truth if tr.stamp_ns > 0][-10:]
    moved = np.max(np.abs(np.asarray(after[-1].q_true) - np.asarray(after[0].q_true)))
    assert moved > np.radians(0.5), "the arm keeps moving on its latched command"
    # the mitigation: restart the bridge on the same device
    restarted = stack.stack._spawn(
        "bridge", ["--can-interface", "slcan", "--can-channel", stack.stack.device]
    )
    t_restart = time.time_ns()
    # the new bridge's first reply stops the latched motion: 0x370 (waiting for power-up),
    # or a zero 0x374 when the arm's first status already shows a move mode

    def stopping() -> list[int]:
        zeros = {t for t, zero in stack.watch.joint_moves(t_restart) if zero}
        return [t for t, i in stack.watch.sent_ids(t_restart) if i == 0x370 or t in zeros]

    stack.wait("a stop from the new bridge", lambda: bool(stopping()), 20.0)
    first = stopping()[0]
    time.sleep(1.0)
    with stack.watch.lock:
        q = [np.asarray(tr.q_true) for tr in stack.watch.truth[-8:]]
    # stopped: what still moves is the new bridge's start-up (initialising: four one-count
    # pulses of motors 4-6, +1 -1 +1 -1, 0.3 deg at most), not the latched command
    assert all(np.allclose(q[0], qi, atol=np.radians(0.35)) for qi in q)
    _report(
        "bridge SIGKILL",
        latched_for=(first - t_kill) / 1e6,
        restart_to_stop=(first - t_restart) / 1e6,
    )
    assert restarted.proc.poll() is None


def test_garbage_on_every_key_is_counted_and_nothing_dies(stack: FaultStack) -> None:
    assert stack.node is not None
    node = stack.node
    keys = node.keys
    garbage = [b"", b"\xc1", b"\x93\x01\x02", b"not msgpack at all", bytes(range(256))]
    suffixes = sorted({name.split("#")[0] for name in channel_types()})
    pubs = {s: node.session.declare_publisher(keys(s)) for s in suffixes}
    for _ in range(3):
        for pub in pubs.values():
            for g in garbage:
                pub.put(g)
    refused = 0
    for name in channel_types():
        if name.endswith("#request"):
            q = name.removesuffix("#request")
            for reply in node.session.get(keys(q), payload=b"\xc1", timeout=2.0):
                refused += reply.err is not None
    for pub in pubs.values():
        pub.undeclare()
    time.sleep(1.0)
    assert stack.stack.exited() == []
    logs = {c.name: c.log.read_text(errors="replace") for c in stack.stack.children}
    for name in ("bridge", "controller", "sequencer"):
        assert "bad payload on" in logs[name], name
    # The bridge counts them live: cmd/joint_velocity and estop, three rounds each.
    with stack.watch.lock:
        counted = stack.watch.bridge[-1].bad_payloads
    assert counted >= 2 * 3 * len(garbage), counted
    assert refused >= 5
    # still works: a task runs
    _start_square(stack)
    n = len(garbage) * 3
    print(f"FAULT garbage: {len(suffixes)} keys x {n} payloads, {refused} queries refused")
