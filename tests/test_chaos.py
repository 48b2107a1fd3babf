"""The chaos soak: its schedule, its judge, the simulator's fault door, and (slow) a
36 s soak of the whole stack with a fixed seed."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
from pathlib import Path

import can
import numpy as np
import pytest

from manus.errors import ConfigError, SchemaError
from manus.node import Node
from manus.session import ZenohSettings
from manus_stack.chaos import judge
from manus_stack.chaos.schedule import FAULTS, TASKS, Action, FaultKind, draw, select
from manus_stack.chaos.soak import run_soak
from schemas import endpoints as ep
from schemas.simfault import SimFault, SimFaultReply
from schemas.state import SimTruth
from services.simulator.core import SimCore
from services.simulator.fault_desk import FaultDesk, fault_from_request
from services.simulator.faults import FrameFault, InjectedMessage, Silence, StuckJoint
from services.simulator.live import LiveSim
from services.simulator.truth_log import TruthLine, TruthLog, read_truth_log
from tests.conftest import eventually

MS = 1_000_000

# -- the schedule ------------------------------------------------------------------------


def test_the_schedule_is_seeded_and_draws_every_fault_before_repeating() -> None:
    rounds = draw(7, 2 * len(FAULTS))
    assert rounds == draw(7, 2 * len(FAULTS))
    assert rounds != draw(8, 2 * len(FAULTS))
    first = {r.fault.name for r in rounds[: len(FAULTS)]}
    assert first == {f.name for f in FAULTS}
    assert [r.task for r in rounds[:4]] == list(TASKS)
    assert all(0.15 * r.task.window_s <= r.delay_s <= r.task.window_s for r in rounds)


def test_a_targeted_soak_draws_from_the_rows_named() -> None:
    faults = select("bridge_sigstop, bridge_sigkill", FAULTS, "fault kind(s)")
    assert [f.name for f in faults] == ["bridge_sigkill", "bridge_sigstop"]
    assert select("", TASKS, "task(s)") == TASKS
    rounds = draw(3, 6, faults, select("fold", TASKS, "task(s)"))
    assert {r.fault.name for r in rounds} == {"bridge_sigkill", "bridge_sigstop"}
    assert {r.task.name for r in rounds} == {"fold"}
    with pytest.raises(ConfigError, match=r"unknown task\(s\) melt \(known: square, gripper"):
        select("fold,melt", TASKS, "task(s)")


def test_fault_kinds_are_checked_when_built() -> None:
    with pytest.raises(ConfigError, match="a target iff"):
        FaultKind("x", Action.SIGKILL)
    with pytest.raises(ConfigError, match="`sim` fields iff"):
        FaultKind("x", Action.SIM)
    with pytest.raises(ConfigError, match="hold_s"):
        FaultKind("x", Action.ESTOP, hold_s=0.0)
    assert len({f.name for f in FAULTS}) == len(FAULTS)


def test_every_task_and_sim_fault_of_the_tables_is_valid() -> None:
    for task in TASKS:
        assert task.task().steps, task.name
    for fault in FAULTS:
        if fault.action is Action.SIM:
            fault_from_request(SimFault(**fault.sim), 0)


# -- the simulator's fault door ----------------------------------------------------------


def test_a_request_becomes_a_fault_on_the_simulator_clock() -> None:
    drop = fault_from_request(
        SimFault(kind="drop", start_in_ms=5, duration_ms=600, ids=[864]), 2 * 10**9
    )
    assert drop == FrameFault("drop", start_ms=2005.0, duration_ms=600.0, ids=(864,))
    error = fault_from_request(SimFault(kind="error", code=4), 10**9)
    assert error == InjectedMessage("error", 4, 1000.0)
    assert fault_from_request(SimFault(kind="silence"), 0) == Silence(0.0, None)
    assert fault_from_request(SimFault(kind="stuck", joint=5), 0) == StuckJoint(5, 0.0, None)
    assert fault_from_request(SimFault(kind="clear"), 0) is None
    with pytest.raises(ConfigError, match="delay_ms"):
        fault_from_request(SimFault(kind="delay", delay_ms=0.0), 0)
    with pytest.raises(SchemaError, match="kind"):
        SimFault(kind="melt")


def test_the_desk_switches_faults_on_and_off_in_the_running_core() -> None:
    core = SimCore()
    bus = can.Bus(interface="virtual", channel="chaos-desk", receive_own_messages=False)
    try:
        desk = FaultDesk(LiveSim(core, bus))
        assert desk(SimFault(kind="drop")).ok
        assert core.advance(2000 * MS) == []
        assert core.counters.dropped > 0
        refused = desk(SimFault(kind="delay", delay_ms=0.0))
        assert not refused.ok and "delay_ms" in refused.message
        assert desk(SimFault(kind="clear")).message == "cleared"
        assert core.advance(3000 * MS)
        assert (desk.accepted, desk.refused) == (2, 1)
    finally:
        bus.shutdown()


# -- the truth log -------------------------------------------------------------------------


def test_the_truth_log_reads_back_what_was_written(tmp_path: Path) -> None:
    log = TruthLog(tmp_path / "truth.txt")
    q = [0.1, -0.2, 0.3, 1e-17, -1.5707963267948966, 2.0]
    for k in range(3):
        log(SimTruth(stamp_ns=k * 60 * MS, seq=99, q_true=q, q_reported=q, gripper=0.04,
                     xyz=[0.0, 0.0, 0.0], ypr=[0.0, 0.0, 0.0]))  # fmt: skip
    log.close()
    with open(tmp_path / "truth.txt", "a") as f:
        f.write("180000000 3 0.1")  # torn by a kill
    lines = read_truth_log(tmp_path / "truth.txt")
    assert [line.seq for line in lines] == [0, 1, 2]
    assert lines[2] == TruthLine(120 * MS, 2, tuple(q), 0.04)


# -- the judge -----------------------------------------------------------------------------


def _truth(speeds_deg_s: list[float], start_ns: int = 0) -> list[TruthLine]:
    """Joint 1 at the given speed during each cycle, one sample per cycle."""
    q, out = 0.0, []
    for k, v in enumerate([0.0, *speeds_deg_s]):
        q += np.radians(v) * 0.06
        out.append(TruthLine(start_ns + k * judge.CYCLE_NS, k, (q, 0, 0, 0, 0, 0), 0.0))
    return out


def test_the_stop_is_the_first_quiet_cycle_after_the_fault() -> None:
    truth = _truth([10.0] * 5 + [0.0] * 5)  # moving until 300 ms
    s = judge.stop_after(truth, fault_ns=200 * MS, until_ns=600 * MS, end_ns=600 * MS)
    assert s == judge.Stop(300 * MS, None)
    never = judge.stop_after(_truth([10.0] * 10), 100 * MS, 600 * MS, 600 * MS)
    assert never.stop_ns is None


def test_motion_after_the_stop_is_resuming_by_itself() -> None:
    truth = _truth([10.0] * 3 + [0.0] * 3 + [5.0] * 3)
    s = judge.stop_after(truth, 100 * MS, until_ns=540 * MS, end_ns=540 * MS)
    assert s == judge.Stop(180 * MS, 360 * MS)
    assert judge.first_motion(truth, 180 * MS, 360 * MS) is None
    assert judge.first_motion(truth, 180 * MS, 540 * MS) == 360 * MS
    assert judge.largest_motion(truth, 360 * MS, 540 * MS) == pytest.approx(np.radians(0.9))


def test_a_gap_in_the_truth_is_neither_quiet_nor_moving() -> None:
    truth = _truth([0.0] * 4)
    jumped = [*truth[:2], TruthLine(truth[2].stamp_ns + 2 * judge.CYCLE_NS, 9, (1.0,) * 6, 0.0)]
    assert judge.first_motion(jumped, 0, 10**12) is None


def test_slow_drift_within_the_tolerance_is_at_rest() -> None:
    assert judge.first_motion(_truth([0.5] * 5), 0, 10**12) is None  # 0.03 deg per cycle
    assert judge.first_motion(_truth([1.0] * 5), 0, 10**12) == 0  # 0.06 deg per cycle


def test_the_reason_must_name_the_fault() -> None:
    assert judge.names_fault("step 2 (move): controller is gone", ("controller",))
    assert not judge.names_fault("no joint states from the arm", ("can_bridge",))
    assert judge.names_fault("anything", ())


def test_completeness_counts_what_a_live_recorder_lacks() -> None:
    samples = [("p/a", b"1", 10), ("p/a", b"2", 20), ("p/b", b"3", 30), ("p/b", b"4", 99)]
    c = judge.completeness(samples, [(0, 50)], {("p/a", b"1")}, "p")
    assert c == judge.Completeness(expected=3, lost=2, lost_by_key={"a": 1, "b": 1})


def test_a_token_is_gone_from_its_vanishing_to_its_return() -> None:
    changes = [(5, True), (10, False), (12, False), (20, True), (30, True), (40, False)]
    assert judge.token_gaps(changes) == [(10, 20), (40, 2**63 - 1)]
    assert judge.token_gaps([(5, True)]) == []


def test_seq_gaps_count_numbered_messages_missing_inside_one_recorder_life() -> None:
    records = [("k", 0, 10), ("k", 1, 20), ("k", 4, 30),  # 2 missing
               ("k", 0, 40), ("k", 2, 50),  # restarted publisher, then 1 missing
               ("k", 9, 70)]  # fmt: skip  # across two recorder lives: not counted
    assert judge.seq_gaps(records, [(0, 55), (60, 80)]) == {"k": 3}


def test_a_hang_seen_only_by_the_deadman_is_judged_against_the_cycles_it_waits() -> None:
    assert judge.stop_limit_ns() == judge.STOP_LIMIT_NS == 180 * MS
    assert judge.stop_limit_ns(0.1) == 240 * MS  # a 0.1 s deadman: one cycle more
    assert judge.stop_limit_ns(0.15) == 300 * MS  # the sequencer's: one echo may come late
    assert judge.stop_limit_ns(0.12) == 300 * MS  # an echo 120 ms old is not too old
    kinds = {f.name: f for f in FAULTS}
    assert [n for n, f in kinds.items() if f.deadman] == ["sequencer_sigstop"]


# -- the soak ------------------------------------------------------------------------------

OPEN: dict[tuple[str, str], str] = {
    **{
        (kind, "move"): "under CPU load a move could abort on the deadman (at 0.1 s, an echo "
        "over 40 ms late: 5 of 33 moves at load 4; 0.15 s since 2026-11-26, not rerun)"
        for kind in ("record_sigkill", "record_sigstop")
    },
}
"""(fault kind, step hit) that violate an invariant today, and why (docs/deployment.md,
chaos soak). A violation by any other pair fails the soak test."""


def _open(violation: dict[str, object]) -> bool:
    """Known: the pair, or the aftermath (the next task failed before its own fault) of a
    fault whose every case is known."""
    fault, step = str(violation["fault"]), str(violation["step"])
    if "after" in violation:
        return (str(violation["after"]), "*") in OPEN
    return (fault, "*") in OPEN or (fault, step) in OPEN


def test_no_bridge_fault_nor_its_aftermath_is_tolerated_any_more() -> None:
    """The guardian stops the arm after a bridge SIGKILL or SIGSTOP, and the next task's
    fold no longer meets a stale bridge phase (docs/deployment.md, Chaos soak)."""
    for kind in ("bridge_sigkill", "bridge_sigstop"):
        assert not _open({"fault": kind, "step": "fold_out"})
        assert not _open({"fault": "e_stop", "step": "fold_in", "after": kind})
    assert _open({"fault": "record_sigkill", "step": "move"})  # what is still known


SOAK_SEED = 8
"""Its first five rounds: a hung sequencer (the deadman alone sees it) in a move, a
duplicated CAN frame, a hung controller, a killed bridge (the guardian) and an arm error:
one of each way a fault reaches the arm (``manus bench chaos`` runs every kind)."""


@pytest.mark.slow(long=True)  # one of the longest units: first in a lane (tests/scheduling.py)
def test_a_short_soak_with_a_fixed_seed(tmp_path: Path) -> None:
    figures = run_soak(tmp_path / "run", minutes=0.6, seed=SOAK_SEED, out=None)
    assert figures["faults_injected"] >= 3, figures
    kinds = [r["fault"] for r in figures["rounds"]]
    assert kinds == [r.fault.name for r in draw(SOAK_SEED, len(kinds))], kinds
    assert figures["tasks_run"] >= figures["faults_injected"]
    for v in figures["invariant_violations"]:
        assert set(v) >= {"round", "fault", "step", "t_s", "what"}
    unexpected = [v for v in figures["invariant_violations"] if not _open(v)]
    assert not unexpected, f"in {figures['run_dir']}:\n" + "\n".join(
        f"round {v['round']} {v['fault']} on {v['task']} ({v['step']}, {v['t_s']} s"
        f"{', after ' + str(v['after']) if 'after' in v else ''}): {v['what']}"
        for v in unexpected
    )
    assert figures["recorder_lost_messages"] == 0, figures["recorder_lost_by_key"]
    assert figures["recorder_expected_messages"] > 1000
    stopping = {r["fault"] for r in figures["rounds"] if "stop_ms" in r}
    assert stopping and stopping <= set(figures["worst_stop_ms"]) | {
        r["fault"] for r in figures["rounds"] if r.get("stop_ms") is None
    }


@pytest.mark.slow
def test_a_running_sim_takes_faults_through_its_door(
    tmp_path: Path, router_endpoint: str, zenoh_settings: ZenohSettings
) -> None:
    truth_file = tmp_path / "truth.txt"
    cmd = [
        sys.executable, "-m", "manus_stack.cli", "sim", "--no-wait-client", "--duration", "6",
        "--zenoh-connect", router_endpoint, "--prefix", "test", "--truth-log", str(truth_file),
    ]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        with Node("chaos-test", zenoh_settings, liveliness=False) as node:
            key = node.keys(ep.SIM_FAULT)
            eventually(lambda: "simulator" in node.alive_services(timeout=0.3), 10.0, "sim up")
            reply = node.query(key, SimFault(kind="drop", ids=[0x360], count=5), SimFaultReply)
            assert reply.ok and reply.start_ns == reply.sim_time_ns >= 0, reply
            refused = node.query(key, SimFault(kind="delay", delay_ms=0.0), SimFaultReply)
            assert not refused.ok and "delay_ms" in refused.message
        _, err = proc.communicate(timeout=20.0)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    stats = json.loads(next(li for li in err.splitlines() if li.startswith("stats: "))[7:])
    assert stats["dropped"] == 5
    lines = read_truth_log(truth_file)
    assert len(lines) >= 60 and [t.seq for t in lines] == list(range(len(lines)))
    assert all(b.stamp_ns - a.stamp_ns == judge.CYCLE_NS for a, b in itertools.pairwise(lines))


def test_ready_after_a_recovery_needs_a_bridge_state_from_after_it() -> None:
    """A restarted bridge says nothing for seconds, and the last state the soak saw is the
    dead bridge's `running`: the stack is not ready on it (it was, once, and the restarted
    bridge's start-up moves were judged as the arm moving by itself)."""
    from types import SimpleNamespace

    from manus_stack.chaos.watch import Seen, Watcher

    w = Watcher.__new__(Watcher)  # no bus: only what the soak saw
    w.seen = Seen()
    w.seen.bridge.append(SimpleNamespace(phase="running", stamp_ns=1_000))  # type: ignore[arg-type]
    assert w.phase() == w.phase(1_000) == "running"
    assert w.phase(1_001) == ""  # recovered at 1001: nothing from the new bridge yet
    w.seen.bridge.append(SimpleNamespace(phase="initialising", stamp_ns=2_000))  # type: ignore[arg-type]
    assert w.phase(1_001) == "initialising"
