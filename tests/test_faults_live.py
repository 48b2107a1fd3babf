"""Fault tests on one host: the real processes of ``manus up``, faults made by the test.

Each test brings up the stack (router, simulator starting unfolded, bridge, planner,
controller, sequencer; Zenoh lease ``LEASE_MS`` for every process), starts the thesis
square through the sequencer, makes one fault on a process it started (by pid) and reads
the outcome from the bridge's raw ``can/tx`` frames, the simulator's truth and the
sequencer's events. Stop times are printed (``-s``) as figures, not asserted tightly:
what is asserted is the rule (zeros, nothing moving on a stale command, the task failed).
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from subprocess import PIPE
from typing import Any

import numpy as np
import pytest

from manus_stack.fuzz_live import fuzz_live
from manus_stack.ports import free_port
from manus_stack.status import node_health
from manus_stack.up import Child
from schemas import endpoints as ep
from services.sequencer.taskfile import task_from_args
from tests.fault_stack import LEASE_MS, ROOT, SQUARE, FaultStack

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


def _speeds(fs: FaultStack, since: int) -> list[float]:
    """Largest true joint speed [deg/s] of each truth from index ``since`` on."""
    with fs.watch.lock:
        return [math.degrees(max(map(abs, tr.qd_true))) for tr in fs.watch.truth[since:]]


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGSTOP])
def test_bridge_killed_or_hung_the_guardian_stops_the_arm_and_a_new_bridge_takes_over(
    stack: FaultStack, sig: signal.Signals
) -> None:
    """SIGKILL or SIGSTOP leaves the bridge no chance to send anything, and the arm repeats
    its last command (docs/protocol.md, The 60 ms cycle). The guardian, another node on the
    bus, sends 0x370 at the first sync left unanswered. Then the bridge comes back (SIGCONT,
    or a new process as compose's ``restart: on-failure`` would start) and takes over:
    nothing moves by itself, and the next task runs."""
    _start_square(stack)
    bridge = stack.child("bridge")
    with stack.watch.lock:
        mark = len(stack.watch.truth)
    t_fault = time.time_ns()
    os.kill(bridge.proc.pid, sig)
    time.sleep(1.0)
    speeds = _speeds(stack, mark)  # one truth per cycle (60 ms)
    assert speeds[0] > 1.0, "it was moving"
    moving = [k for k, v in enumerate(speeds) if v >= 0.05]
    rest_cycles = moving[-1] + 1 if moving else 0
    assert rest_cycles < len(speeds) - 3, "at rest for good"
    with stack.watch.lock:
        stops = [r for r in stack.watch.guardian if r.action == "stop_sent"]
    assert stops and stops[-1].engaged
    if sig == signal.SIGKILL:
        stack.stack.respawn(bridge)
    else:
        os.kill(bridge.proc.pid, signal.SIGCONT)
    with stack.watch.lock:
        mark = len(stack.watch.truth)
    t_back = time.time_ns()

    def running() -> bool:
        with stack.watch.lock:
            last = stack.watch.bridge[-1]
        return last.stamp_ns > t_back and last.phase == "running"

    stack.wait("the bridge running again", running, 20.0)
    t_running = time.time_ns()
    time.sleep(1.0)
    with stack.watch.lock:
        q = [np.asarray(tr.q_true) for tr in stack.watch.truth[mark:]]
        back = [r for r in stack.watch.guardian if r.action == "bridge_back"]
    # nothing resumed: what may move is a new bridge's start-up (four one-count pulses of
    # motors 4-6, 0.3 deg at most), not the path
    assert all(np.allclose(q[0], qi, atol=np.radians(0.35)) for qi in q)
    assert back, "the guardian saw the bridge answer again"
    _report(
        f"bridge {sig.name} with the guardian",
        at_rest_within=rest_cycles * CYCLE_MS,
        back_running=(t_running - t_back) / 1e6,
        fault_to_recovery=(t_back - t_fault) / 1e6,
    )
    # the next task runs on the bridge that took over
    _start_square(stack)


def test_fuzz_on_every_key_and_queryable_is_counted_and_nothing_dies(stack: FaultStack) -> None:
    """Seeded bad payloads (manus_stack.fuzz) on every key and queryable of
    ``channel_types()``: no process dies, each service counts every one it received where
    ``manus status`` shows it (NodeHealth), each queryable refuses them, a task runs after."""
    assert stack.node is not None
    node = stack.node
    per = 8
    # a refusal is not a deadline: under load the planner once took more than the default
    # second to refuse one plan query (a query nobody serves returns at once, whatever this)
    done = fuzz_live(node, seed=0, per_endpoint=per, query_timeout=5.0)
    subscribed = {"state/joints", "state/status", "state/bridge", "cmd/joint_velocity", "estop"}
    subscribed |= {"heartbeat", "controller/feedback", "controller/result"}
    queryables = set(done.refused) | set(done.unanswered)
    # A running `manus replay` answers replay/control; none runs here: nobody answers.
    assert done.unanswered.get(ep.PLAYBACK_CONTROL) == per
    queryables.discard(ep.PLAYBACK_CONTROL)
    health: dict[str, dict[str, Any]] = {}
    missing: list[str] = []

    def all_counted() -> bool:
        """Each service counts on its own threads, and answers health within 1 s: the
        counts are read until they hold everything sent (under load, a second after the
        last payload was once too early)."""
        nonlocal health, missing
        health = node_health(node)
        keys = {k for h in health.values() for k in h["by_key"]}
        missing = sorted((subscribed | queryables) - keys)
        missing += [f"{s}: {k} {n} of {done.sent[k]}" for s, h in health.items()
                    for k, n in h["by_key"].items() if n < done.sent[k]]  # fmt: skip
        return not missing

    try:
        stack.wait("every bad payload counted", all_counted, 15.0)
    except AssertionError as exc:
        raise AssertionError(f"{exc}; short: {missing}; services {sorted(health)}") from None
    assert stack.stack.exited() == []
    counted: dict[str, int] = {}
    for service, h in health.items():
        for key, n in h["by_key"].items():
            assert n == done.sent[key], (service, key, n)  # every one, none lost
            counted[key] = counted.get(key, 0) + n
    assert subscribed <= set(counted), sorted(subscribed - set(counted))
    for q in queryables:
        assert done.refused.get(q) == per and q in counted, (q, done)

    # the bridge counts its own live too (BridgeState.bad_payloads, in its next state)
    def bridge_counted() -> int:
        with stack.watch.lock:
            return stack.watch.bridge[-1].bad_payloads

    want = done.sent["cmd/joint_velocity"] + done.sent["estop"]
    stack.wait("the bridge's own count", lambda: bridge_counted() >= want, 5.0)
    _start_square(stack)  # still works: a task runs
    print(
        f"FUZZ live: {len(done.sent)} endpoints x {per} bad payloads, "
        f"{sum(done.refused.values())} queries refused, counted per key {counted}"
    )


BACK_AND_FORTH = """
0 0 0    0 0 0  0 0 0  0 0 0  0.0 2
0 50 0   0 0 0  0 0 0  0 0 0  2.5 2
0 -50 0  0 0 0  0 0 0  0 0 0  5.0 2
"""
"""50 mm along y and back (relative via points): the arm ends where it started."""


def _client_through(
    stack: FaultStack, argv: list[str], fault: Callable[[], None], timeout: float
) -> tuple[subprocess.Popen[str], str, str, float]:
    """Run the client ``argv`` on a task, make ``fault`` once the arm moves, and wait
    ``timeout`` [s] for the client to exit: the process, its output and error, and how
    long after the fault it exited [s]."""
    proc = subprocess.Popen(argv, cwd=ROOT, stdout=PIPE, stderr=PIPE, text=True)
    try:
        stack.wait_moving()
        assert proc.poll() is None, proc.communicate()
        t_fault = time.monotonic()
        fault()
        out, err = proc.communicate(timeout=timeout)
        return proc, out, err, time.monotonic() - t_fault
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def test_clients_notice_the_sequencer_dying_mid_task(stack: FaultStack, tmp_path: Path) -> None:
    """``manus run``, then examples/supervisor.py, each following a task, exit 1 naming the
    sequencer when its process is killed mid-task: no final event will ever come."""
    path = tmp_path / "back_and_forth.txt"
    path.write_text(BACK_AND_FORTH)
    endpoint, prefix = stack.options.endpoint, stack.options.prefix
    run = [sys.executable, "-m", "manus_stack.cli", "run", "--plain", "--connect", endpoint]
    sup = [sys.executable, str(ROOT / "examples" / "supervisor.py"), "--connect", endpoint]
    for name, head in (("manus run", run), ("supervisor", sup)):
        sequencer = stack.child("sequencer")

        def kill(sequencer: Child = sequencer) -> None:
            os.kill(sequencer.proc.pid, signal.SIGKILL)
            sequencer.proc.wait(timeout=5.0)

        argv = [*head, "--prefix", prefix, str(path)]
        proc, out, err, took = _client_through(stack, argv, kill, 10.0)
        _report(f"sequencer SIGKILL, {name}", exited_after=took * 1e3)
        assert proc.returncode == 1, (out, err)
        assert "sequencer" in out + err and "gone" in out + err, (out, err)
        assert took < 3.0  # the token's loss: a closed connection, well under a second
        # a new sequencer for the next client (compose would restart it)
        stack.stack.respawn(sequencer)
        stack.wait("a sequencer", lambda: "sequencer" in stack.node.alive_services(0.5), 20.0)  # type: ignore[union-attr]
        time.sleep(1.0)  # the controller's aborted goal has stopped the arm


def _restart_router(stack: FaultStack, down_s: float) -> None:
    """Kill the router (every link cut), start it again ``down_s`` later."""
    router = stack.child("router")
    os.kill(router.proc.pid, signal.SIGKILL)
    router.proc.wait(timeout=5.0)
    time.sleep(down_s)
    stack.stack.respawn(router)


def test_clients_learn_how_a_task_ended_through_a_router_restart(
    stack: FaultStack, tmp_path: Path
) -> None:
    """A router restart mid-task (every link cut; the task fails while the clients' links
    are down, its final event reaches nobody): ``manus run`` and examples/supervisor.py
    each wait for the link and the sequencer's token, read the final event from
    ``sequencer/history`` and exit 1 with it, shown once; neither takes the cut for the
    sequencer's death."""
    path = tmp_path / "back_and_forth.txt"
    path.write_text(BACK_AND_FORTH)
    endpoint, prefix = stack.options.endpoint, stack.options.prefix
    run = [sys.executable, "-m", "manus_stack.cli", "run", "--plain", "--connect", endpoint]
    sup = [sys.executable, str(ROOT / "examples" / "supervisor.py"), "--connect", endpoint]
    assert stack.node is not None
    node = stack.node
    for name, head in (("manus run", run), ("supervisor", sup)):
        stack.wait("the stack", lambda: "sequencer" in node.alive_services(0.5), 30.0)
        stack.wait("bridge running", lambda: stack.watch.bridge[-1].phase == "running", 30.0)
        argv = [*head, "--prefix", prefix, str(path)]
        proc, out, err, took = _client_through(
            stack, argv, lambda: _restart_router(stack, down_s=1.0), 45.0
        )
        _report(f"router restart, {name}", exited_after=took * 1e3)
        text = out + err
        assert proc.returncode == 1, (out, err)
        assert "sequencer is gone" not in text and "sequencer gone" not in text, (out, err)
        assert "sequencer/history" in text, (out, err)
        finals = [li for li in out.splitlines() if "failed" in li and "step_failed" not in li]
        assert len(finals) == 1, (out, err)  # shown once
        assert any(word in finals[0] for word in ("link", "heartbeat", "gone")), finals
