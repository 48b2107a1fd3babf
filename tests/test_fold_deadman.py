"""A fold's deadman (services/can_bridge/fold_deadman.py), in lock-step on the simulator's
truth: a fold asked with ``heartbeat_timeout`` stops when the supervisor's heartbeats,
the link, the controller or the bridge itself stop, and nothing resumes by itself."""

from __future__ import annotations

import pytest

from manus.protocol import FrameId
from manus_stack.chaos import judge
from manus_stack.lockstep import LockStep
from manus_stack.task_lockstep import TaskLockStep
from schemas.base import Message
from schemas.commands import ArmCommand
from schemas.control import Heartbeat
from schemas.sequencing import Task, TaskStep
from schemas.state import JointState
from services.can_bridge.config import BridgeConfig
from services.controller.core import ControllerCore, Output
from services.sequencer.actions import Action
from services.sequencer.core import SequencerCore
from services.simulator.config import SimConfig
from tests.bridge_scenarios import MS, UNFOLDED, VelocityController, check_safety, running

CYCLE_MS = 60
FOLD_IDS = (FrameId.FOLD_IN, FrameId.FOLD_OUT)


class Supervisor:
    """Echoes every joint state with a Heartbeat while ``alive`` (the sequencer)."""

    def __init__(self) -> None:
        self.alive = True
        self.seq = 0

    def __call__(self, msg: Message, t_ns: int) -> list[tuple[str, Message]]:
        assert isinstance(msg, JointState)
        if not self.alive:
            return []
        self.seq += 1
        hb = Heartbeat(stamp_ns=t_ns, seq=self.seq, source="test", ref_seq=msg.seq,
                       ref_stamp_ns=msg.stamp_ns)  # fmt: skip
        return [("heartbeat", hb)]


def folding(timeout_s: float = 0.1) -> tuple[LockStep, VelocityController, Supervisor]:
    """An unfolded arm folding in for 1 s, with a controller (zeros) and a supervisor."""
    ls = running(UNFOLDED)
    controller, supervisor = VelocityController((0.0,) * 6), Supervisor()
    ls.subscribe("state/joints", controller)
    ls.subscribe("state/joints", supervisor)
    ls.run_for(0.2)
    reply = ls.arm_command(ArmCommand(action="fold_in", source="t", heartbeat_timeout=timeout_s))
    assert reply.ok and reply.phase == "folding_in", reply
    ls.run_for(1.0)
    assert _fold_frames(ls, ls.t_ns - 3 * CYCLE_MS * MS), "not folding"
    return ls, controller, supervisor


def _fold_frames(ls: LockStep, since_ns: int) -> list[int]:
    return [f.t_ns for f in ls.bridge_frames if f.id in FOLD_IDS and f.t_ns >= since_ns]


def _stop_ms(ls: LockStep, seconds: float = 1.0) -> float:
    """Run ``seconds`` from a fault now; the time to the arm's stop as the chaos soak
    judges it on the simulator's truth (the start of the first quiet cycle, and no motion
    after it) [ms]."""
    fault = ls.t_ns
    truth = [judge.from_truth(ls.sim.truth())]
    for _ in range(round(seconds * 1e9 / judge.CYCLE_NS)):
        ls.run_for(judge.CYCLE_NS / 1e9)
        truth.append(judge.from_truth(ls.sim.truth()))
    stop = judge.stop_after(truth, fault, ls.t_ns, ls.t_ns)
    assert stop.stop_ns is not None and stop.resumed_ns is None, stop
    return (stop.stop_ns - fault) / MS


@pytest.mark.parametrize("offset_ms", [5, 25, 45])
def test_a_fold_stops_when_the_heartbeats_stop_and_nothing_resumes(offset_ms: int) -> None:
    ls, _, supervisor = folding()
    last_js = [t for t, s, _ in ls.messages if s == "state/joints"][-1]
    ls.run_until(last_js + CYCLE_MS * MS + offset_ms * MS)
    cut = ls.t_ns
    supervisor.alive = False  # the sequencer is killed, hangs, or the link is cut
    stop_ms = _stop_ms(ls)
    first_stop = min(f.t_ns for f in ls.bridge_frames if f.t_ns >= cut and f.id == FrameId.STOP)
    # the newest echo is at most one cycle older than the cut; the state within 0.1 s of
    # it still folds, the next one stops it: 0x370 at its sync, as a move's deadman does
    assert first_stop - cut <= 2 * CYCLE_MS * MS + 20 * MS, (first_stop - cut) / MS
    assert all(t < first_stop for t in _fold_frames(ls, cut))
    # at 15 deg/s the drives' lag (20 ms) leaves more than the judge's 0.05 deg in the
    # cycle after the 0x370 acts when the cut came just after an echo: one cycle more
    assert stop_ms <= judge.STOP_LIMIT_NS / MS + CYCLE_MS, stop_ms
    assert ls.bridge.phase == "stopped"
    assert ls.bridge.detail.startswith("fold_in stopped: lost the supervisor's heartbeat")
    supervisor.alive = True  # back: nothing resumes by itself
    back = ls.t_ns
    ls.run_for(2.0)
    assert _fold_frames(ls, back) == [] and ls.bridge.phase == "stopped"
    assert {f.id for f in ls.bridge_frames if f.t_ns >= back} == {FrameId.STOP}
    check_safety(ls)


def test_a_fold_stops_when_the_controller_stops_answering() -> None:
    ls, controller, _ = folding()
    controller.stop_after_ns = ls.t_ns  # killed or hung
    dead = ls.t_ns
    stop_ms = _stop_ms(ls)
    sent = [(f.t_ns, f.id) for f in ls.bridge_frames if f.t_ns >= dead]
    # the first sync without an answered joint state gets zeros: the arm pauses at once
    first_zero = next(t for t, fid in sent if fid == FrameId.JOINT)
    assert first_zero - dead <= CYCLE_MS * MS + 20 * MS
    assert all(fid != FrameId.FOLD_IN for t, fid in sent if t > first_zero)
    assert stop_ms <= 2 * CYCLE_MS, stop_ms
    assert ls.bridge.phase == "stopped"
    assert "no command from the controller" in ls.bridge.detail, ls.bridge.detail
    controller.stop_after_ns = None  # SIGCONT, or a new controller: nothing resumes
    back = ls.t_ns
    ls.run_for(2.0)
    assert _fold_frames(ls, back) == []
    assert ls.bridge.health.stale_commands == 0  # a fold's refusals are not velocity commands


def test_one_late_controller_cycle_pauses_the_fold_and_it_goes_on() -> None:
    ls, controller, _ = folding()
    controller.stop_after_ns = ls.t_ns
    t0 = ls.t_ns
    ls.run_for(0.07)  # one joint state unanswered
    controller.stop_after_ns = None
    ls.run_until_phase("running", timeout_s=15.0)
    assert ls.bridge.detail == "fold_in complete"
    assert any(f.id == FrameId.JOINT for f in ls.bridge_frames if t0 <= f.t_ns < t0 + 0.2e9)
    check_safety(ls)


def test_a_bridge_woken_from_sigstop_does_not_go_on_folding() -> None:
    ls, _, _ = folding()
    ls.pause_bridge()
    stopped = ls.t_ns
    ls.run_for(1.0)  # nothing answers the syncs (no guardian here): the fold goes on
    ls.resume_bridge()  # its backlog is no joint state; its heartbeats are old
    woken = ls.t_ns
    ls.run_for(1.0)
    assert _fold_frames(ls, woken) == [], [(t - woken) / MS for t in _fold_frames(ls, woken)]
    assert ls.bridge.phase == "stopped", ls.bridge.detail
    assert stopped < woken


def test_without_a_deadman_a_fold_needs_neither_heartbeats_nor_commands() -> None:
    ls = running(UNFOLDED)
    assert ls.arm_command(ArmCommand(action="fold_in", source="t")).ok
    ls.run_until_phase("running", timeout_s=15.0)
    assert ls.bridge.detail == "fold_in complete"


def test_the_missed_cycles_setting_is_checked() -> None:
    from manus.errors import ConfigError

    with pytest.raises(ConfigError, match="fold_missed_cycles_to_stop"):
        BridgeConfig(fold_missed_cycles_to_stop=0)


# -- through the sequencer --------------------------------------------------------------


class Mortal(SequencerCore):
    """A sequencer that can be killed: it gets nothing and says nothing."""

    running = True

    def on_joint_state(self, js: JointState, now_ns: int) -> list[Action]:
        return super().on_joint_state(js, now_ns) if self.running else []

    def on_tick(self, now_ns: int) -> list[Action]:
        return super().on_tick(now_ns) if self.running else []


class MortalController(ControllerCore):
    """A controller that can be killed."""

    running = True

    def on_joint_state(self, js: JointState) -> Output:
        return super().on_joint_state(js) if self.running else []


def fold_task_rig(controller: ControllerCore | None = None) -> TaskLockStep:
    rig = TaskLockStep(SimConfig(start_pose="unfolded"), controller=controller)
    rig.seq = Mortal()
    for name in rig.seq.config.required_services:
        rig.seq.on_liveliness(name, True, 0)
    rig.start_arm()
    assert rig.submit(Task(steps=[TaskStep(kind="fold_in")])).accepted
    rig.ls.run_for(1.5)
    assert rig.ls.bridge.phase == "folding_in"
    return rig


def test_the_sequencer_asks_for_the_deadman_and_a_killed_one_stops_the_fold() -> None:
    rig = fold_task_rig()
    folds = [r for r in rig.requests if isinstance(r, ArmCommand)]
    assert folds[-1].heartbeat_timeout == pytest.approx(0.15)
    assert isinstance(rig.seq, Mortal)
    rig.seq.running = False
    # one cycle past the soak's limit: the fold's deadman lets one echo come a cycle late
    # (fold_heartbeat_timeout_s 0.15 s, against false stops under load)
    assert _stop_ms(rig.ls) <= judge.STOP_LIMIT_NS / MS + CYCLE_MS
    assert rig.ls.bridge.phase == "stopped"


def test_a_killed_controller_stops_the_fold_and_the_task_fails_naming_it() -> None:
    controller = MortalController()
    rig = fold_task_rig(controller)
    controller.running = False
    assert _stop_ms(rig.ls) <= 2 * CYCLE_MS
    assert rig.seq.state == "failed"
    assert "phase stopped" in rig.seq.reason and "controller" in rig.seq.reason, rig.seq.reason


def test_a_late_joint_state_is_judged_one_cycle_after_the_one_before_it() -> None:
    """The arm's side starved (a joint state 250 ms after the one before it) while every
    state was echoed: no echo of the late state can exist yet, so it is no lost
    heartbeat; when the echoes stop, the fold stops at the same state as without it."""
    from services.can_bridge.fold_deadman import FoldDeadman

    ms = 1_000_000
    late = FoldDeadman(heartbeat_timeout_s=0.1, missed_to_stop=5)
    stamps = [0, 60, 120, 370, 430]  # 370: 250 ms late
    echoes = [None, 0, 60, 120, 370]
    assert [late.on_joint_state(t * ms, k, e if e is None else e * ms)
            for k, (t, e) in enumerate(zip(stamps, echoes, strict=True))] == [None] * 5  # fmt: skip
    # the echoes stop after 430: stopped at the second state after it, as on time
    assert late.on_joint_state(490 * ms, 5, 430 * ms) is None
    assert late.on_joint_state(550 * ms, 6, 430 * ms) is not None
    # a late state whose predecessor went unechoed still stops the fold
    cut = FoldDeadman(heartbeat_timeout_s=0.1, missed_to_stop=5)
    assert cut.on_joint_state(0, 0, None) is None
    assert cut.on_joint_state(60 * ms, 1, 0) is None
    why = cut.on_joint_state(310 * ms, 2, 0)
    assert why is not None and "120 ms before joint state seq 2" in why
    # more than 5 cycles without a joint state (a bridge held up): stopped whatever echoes
    held = FoldDeadman(heartbeat_timeout_s=0.1, missed_to_stop=5)
    assert held.on_joint_state(0, 0, None) is None
    why = held.on_joint_state(400 * ms, 1, 0)
    assert why is not None and why.startswith("no joint state for 400 ms")
