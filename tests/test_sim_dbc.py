"""schemas/manus.dbc decodes the simulator's frames exactly as manus.protocol does."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, cast

import cantools
import pytest

from manus.protocol import (
    FrameId,
    MoveCommand,
    decode_position,
    decode_status,
    encode_move,
)
from services.simulator.config import SimConfig
from services.simulator.core import SimCore
from services.simulator.faults import FaultConfig, InjectedMessage
from services.simulator.scripted import ScriptedPc, joint_move

DBC = Path(__file__).resolve().parent.parent / "schemas" / "manus.dbc"


@pytest.fixture(scope="module")
def db() -> cantools.database.can.Database:
    loaded = cantools.database.load_file(str(DBC))
    assert isinstance(loaded, cantools.database.can.Database)
    return loaded


def _decode(
    db: cantools.database.can.Database, frame_id: int, data: bytes, *, choices: bool = False
) -> dict[str, Any]:
    return dict(cast(Mapping[str, Any], db.decode_message(frame_id, data, decode_choices=choices)))


def test_every_protocol_frame_is_described(db: cantools.database.can.Database) -> None:
    lengths = {m.frame_id: m.length for m in db.messages}
    assert lengths == {
        FrameId.STATUS: 8,
        FrameId.POSITION: 8,
        FrameId.SYNC: 0,
        FrameId.STOP: 0,
        FrameId.CARTESIAN: 8,
        FrameId.JOINT: 8,
        FrameId.FOLD_OUT: 0,
        FrameId.FOLD_IN: 0,
    }


def test_simulator_frames_decode_the_same_with_cantools(
    db: cantools.database.can.Database,
) -> None:
    faults = FaultConfig(messages=(InjectedMessage("warning", 3, at_ms=1000, duration_ms=120),))
    core = SimCore(SimConfig(start_pose="unfolded", faults=faults))
    pc = ScriptedPc(core)
    pc.enter_joint_mode()
    pc.run_cycles(20, joint_move(-10, 7, -3, 4, -5, 6, gripper=9))
    checked = 0
    for f in pc.frames:
        if f.id == FrameId.STATUS:
            ours = decode_status(f.data)
            theirs = _decode(db, f.id, f.data)
            assert theirs["Mode"] == ours.mode
            assert theirs["MsgClass"] << 6 == int(ours.msg_class)
            assert theirs["MsgCode"] == ours.msg_code
            got = tuple(round(theirs[f"Joint{i}"] * 10) for i in (1, 2, 3))
            assert got == ours.fields
            checked += 1
        elif f.id == FrameId.POSITION:
            pos = decode_position(f.data)
            theirs = _decode(db, f.id, f.data)
            assert tuple(round(theirs[f"Joint{i}"] * 10) for i in (4, 5, 6)) == pos.fields
            assert round(theirs["Gripper"] * 10) == pos.gripper
            checked += 1
    assert checked > 40
    choices = _decode(db, FrameId.STATUS, pc.frames[-3].data, choices=True)
    assert str(choices["Mode"]) == "joint"


def test_commands_encode_the_same_with_cantools(db: cantools.database.can.Database) -> None:
    joint = MoveCommand(FrameId.JOINT, 0, (-10, 7, -3, 4, -5, 6), -15)
    values = {"Lift": 0, "Gripper": -1.5}
    values |= {f"Joint{i + 1}": v * 0.1 for i, v in enumerate(joint.axes)}
    assert db.encode_message(FrameId.JOINT, values) == encode_move(joint)
    cart = MoveCommand(FrameId.CARTESIAN, 1, (-127, 100, 5, -10, 3, 10), 15)
    values = {"Lift": 1, "X": -127 * 0.022, "Y": 100 * 0.022, "Z": 5 * 0.022}
    values |= {"Yaw": -1.0, "Pitch": 0.3, "Roll": 1.0, "Gripper": 1.5}
    assert db.encode_message(FrameId.CARTESIAN, values) == encode_move(cart)
