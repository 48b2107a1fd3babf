"""Fault injection: each kind observable on its own, from the config and at run time."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from manus.errors import ConfigError
from manus.protocol import FrameId, MessageClass, empty_frame
from services.simulator.config import SimConfig, load_sim_config
from services.simulator.core import MS, SimCore
from services.simulator.faults import (
    DUPLICATE_GAP_NS,
    FaultConfig,
    FrameFault,
    InjectedMessage,
    Silence,
    StuckJoint,
    parse_fault_list,
)
from services.simulator.scripted import ScriptedPc, joint_move


def _frames(*faults: FrameFault | Silence, seed: int = 0) -> SimCore:
    return SimCore(SimConfig(seed=seed, faults=parse_fault_list(faults)))


def test_drop_a_burst_of_one_frame_kind() -> None:
    core = _frames(FrameFault("drop", start_ms=300, duration_ms=300, ids=(FrameId.POSITION,)))
    frames = core.advance(1200 * MS)
    lost = [t for t in range(40, 1200, 60) if not any(f.t_ns == t * MS for f in frames)]
    assert lost == [340, 400, 460, 520, 580]
    assert core.counters.dropped == 5
    assert len(frames) == 60 - 5


def test_drop_at_a_rate_is_seeded() -> None:
    def sent(seed: int) -> list[int]:
        core = _frames(FrameFault("drop", rate=0.3), seed=seed)
        return [f.t_ns for f in core.advance(6000 * MS)]

    a = sent(1)
    assert a == sent(1) and a != sent(2)
    assert 0.2 < 1 - len(a) / 300 < 0.4


def test_duplicate_frames_follow_half_a_millisecond_later() -> None:
    core = _frames(FrameFault("duplicate", start_ms=100, count=3))
    frames = core.advance(300 * MS)
    times = [f.t_ns for f in frames]
    assert times[:8] == [
        20 * MS,
        40 * MS,
        60 * MS,
        80 * MS,
        100 * MS,
        100 * MS + DUPLICATE_GAP_NS,
        120 * MS,
        120 * MS + DUPLICATE_GAP_NS,
    ]
    assert frames[4] == frames[5].at(frames[4].t_ns)
    assert core.counters.duplicated == 3


def test_delayed_frames_arrive_late_and_out_of_order() -> None:
    core = _frames(FrameFault("delay", delay_ms=30, ids=(FrameId.STATUS,), count=1, start_ms=60))
    frames = core.advance(200 * MS)
    order = [(f.id, f.t_ns // MS) for f in frames if f.t_ns >= 60 * MS][:4]
    assert order == [(0x37F, 60), (0x360, 100), (0x350, 110), (0x37F, 120)]
    assert core.counters.delayed == 1


@pytest.mark.parametrize("how", ["bits", "dlc"])
def test_corrupted_frames(how: str) -> None:
    clean = SimCore().advance(600 * MS)
    core = _frames(FrameFault("corrupt", corrupt=how, ids=(FrameId.STATUS, FrameId.SYNC)))
    bad = core.advance(600 * MS)
    assert len(bad) == len(clean) and core.counters.corrupted == 20
    for a, b in zip(clean, bad, strict=True):
        if a.id == FrameId.POSITION:
            assert a == b
        elif how == "dlc" or a.remote:
            assert b.dlc != a.dlc
        else:
            diff = int.from_bytes(a.data, "big") ^ int.from_bytes(b.data, "big")
            assert diff.bit_count() == 1


def test_silence_stops_every_frame_but_the_cycle_goes_on() -> None:
    core = _frames(Silence(start_ms=200, duration_ms=400))
    frames = core.advance(1000 * MS)
    times = [f.t_ns // MS for f in frames]
    assert not [t for t in times if 200 <= t < 600]
    assert times[times.index(600) :][:4] == [600, 620, 640, 660]
    assert core.counters.silenced == 20


def test_an_injected_error_latches_stops_the_arm_until_0x370() -> None:
    core = SimCore()
    pc = ScriptedPc(core)
    pc.enter_joint_mode()
    pc.run_cycles(3, joint_move(5))
    core.add_fault(InjectedMessage("error", 13, at_ms=core.time_ns / MS + 1))
    pc.run_cycles(3, joint_move(5))
    stopped = core.encoder_counts()
    pc.run_cycles(5, joint_move(5))
    assert core.encoder_counts() == stopped
    assert core.counters.ignored_in_error >= 5
    assert {(c.status.msg_class, c.status.msg_code) for c in pc.cycles[-5:]} == {
        (MessageClass.ERROR, 13)
    }
    pc.run_cycles(1, empty_frame(FrameId.STOP))
    pc.run_cycles(1, joint_move(5))
    pc.run_cycles(3)
    assert core.error is None and core.encoder_counts()[0] > stopped[0]
    assert pc.cycles[-1].status.msg_class == MessageClass.NONE


def test_an_injected_warning_holds_for_its_duration() -> None:
    core = SimCore(
        SimConfig(
            faults=FaultConfig(
                messages=(InjectedMessage("warning", 5, at_ms=1000, duration_ms=200),)
            )
        )
    )
    pc = ScriptedPc(core)
    pc.run(1500 * MS)
    warned = [c.t_ns // MS for c in pc.cycles if c.status.msg_class == MessageClass.WARNING]
    assert warned == [1040, 1100, 1160, 1220]


def test_a_stuck_joint_stops_while_the_others_move() -> None:
    core = SimCore()
    pc = ScriptedPc(core)
    pc.enter_joint_mode()
    core.add_fault(StuckJoint(1, at_ms=core.time_ns / MS))
    before = core.encoder_counts()
    pc.run_cycles(8, joint_move(5, 0, 5))
    after = core.encoder_counts()
    assert after[0] == before[0] and after[2] > before[2]
    codes = [
        c.status.msg_code for c in pc.cycles[-4:] if c.status.msg_class == MessageClass.WARNING
    ]
    assert codes == [3, 3, 3, 3]


def test_faults_can_be_switched_on_and_off_at_run_time() -> None:
    core = SimCore()
    core.advance(120 * MS)
    core.add_fault(FrameFault("drop", ids=(FrameId.SYNC,)))
    assert not [f for f in core.advance(600 * MS) if f.id == FrameId.SYNC]
    core.clear_faults()
    assert [f for f in core.advance(700 * MS) if f.id == FrameId.SYNC]


def test_faults_load_from_a_json_config(tmp_path: Path) -> None:
    path = tmp_path / "sim.json"
    path.write_text(
        json.dumps(
            {
                "seed": 4,
                "start_pose": "unfolded",
                "backlash_deg": [0.2, 0, 0, 0.5, 0.5, 0.5],
                "arm": {"l4_mm": 150},
                "faults": {
                    "frames": [{"kind": "drop", "rate": 0.5, "ids": [0x360]}],
                    "silences": [{"start_ms": 5000, "duration_ms": 100}],
                    "messages": [{"msg_class": "error", "code": 1, "at_ms": 9000}],
                    "stuck": [{"joint": 5, "at_ms": 100}],
                },
            }
        )
    )
    cfg = load_sim_config(path, seed=9)
    assert cfg.seed == 9 and cfg.arm.l4 == pytest.approx(0.150)
    assert cfg.faults.frames == (FrameFault("drop", rate=0.5, ids=(0x360,)),)
    assert cfg.faults.stuck == (StuckJoint(5, at_ms=100),)
    assert cfg.backlash_deg == (0.2, 0.0, 0.0, 0.5, 0.5, 0.5)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"faults": {"frames": [{"kind": "explode"}]}}, "frame fault kind 'explode'"),
        ({"faults": {"frames": [{"kind": "drop", "rate": 2}]}}, "`rate` 2 outside"),
        ({"faults": {"stuck": [{"joint": 7}]}}, "stuck joint 7 outside 1..6"),
        ({"faults": {"oops": []}}, "unknown fault family `oops`"),
        ({"transient_tau_ms": -1}, "`transient_tau_ms` must be in [0, 1000]"),
        ({"first_motion_delay_ms": 50}, "multiple of the 20 ms tick"),
        ({"start_pose": [0, 0, 0, 0, 150, 0]}, "joint 5 at 150.0 deg is outside"),
        ({"start_pose": "upside-down"}, "`start_pose` 'upside-down'"),
        ({"colour": "red"}, "unknown simulator setting `colour`"),
    ],
)
def test_bad_settings_name_the_value_and_the_limit(data: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=message.replace("[", r"\[").replace("(", r"\(")):
        SimConfig.from_mapping(data, source="sim.json")
