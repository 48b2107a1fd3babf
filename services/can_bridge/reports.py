"""From the arm's frames to SI messages: joint state, arm status, the frames themselves.

Frames and units: docs/protocol.md, Frames from the arm; Encoder map.

Joint fields are motor angles in 0.1 deg; the joint map (:mod:`manus.joint_map`) turns
them into DH angles [rad]. The gripper field is the opening in 0.1 mm (the project's
choice), published in metres. The speed steps the arm executes are published as DH
joint and gripper velocities (:func:`manus.quantize.step_rates`): past the bridge,
every service sees SI only.
"""

from __future__ import annotations

import math

import numpy as np

from manus.joint_map import encoder_to_dh
from manus.protocol import (
    GRIPPER_UNIT_MM,
    JOINT_UNIT_DEG,
    Frame,
    MessageClass,
    Mode,
    PositionFrame,
    StatusFrame,
    message_text,
)
from manus.quantize import GRIPPER_COUNT_M_S, step_rates
from schemas.state import ArmStatus, CanFrame, JointState

_MODE_NAMES = {
    Mode.NONE: "none",
    Mode.CARTESIAN: "cartesian",
    Mode.JOINT: "joint",
    Mode.FOLD_OUT: "fold_out",
    Mode.FOLD_IN: "fold_in",
}
_CLASS_NAMES = {
    MessageClass.NONE: "none",
    MessageClass.WARNING: "warning",
    MessageClass.GENERAL: "general",
    MessageClass.ERROR: "error",
}
_FIELD_RAD = math.radians(JOINT_UNIT_DEG)


def mode_name(nibble: int) -> str:
    """The :data:`schemas.state.MODES` name of a status mode nibble."""
    try:
        return _MODE_NAMES[Mode(nibble)]
    except ValueError:
        return "unknown"


def encoder_fields(status: StatusFrame, position: PositionFrame) -> tuple[int, ...]:
    """Joints 1..6 [0.1 deg] and the gripper [0.1 mm] of one cycle."""
    return (*status.fields, *position.fields, position.gripper)


def joint_state(
    status: StatusFrame,
    position: PositionFrame,
    *,
    stamp_ns: int,
    seq: int,
    valid: bool,
    applied: tuple[int, ...],
    applied_kind: str,
    applied_seq: int,
) -> JointState:
    """The joint state of one cycle.

    Args:
        status: the cycle's decoded 0x350.
        position: its decoded 0x360.
        stamp_ns: receive time of the 0x360 [ns].
        seq: this stream's sequence number.
        valid: the positions are meaningful.
        applied: lift, motors 1..6 [counts], gripper [counts] sent at the previous sync
            (published as what they are: DH joint and gripper velocities).
        applied_kind: what was sent then (:data:`schemas.state.APPLIED_KINDS`).
        applied_seq: seq of the velocity command sent then (-1: none).
    """
    motor = np.array((*status.fields, *position.fields), dtype=float) * _FIELD_RAD
    q = encoder_to_dh(motor)
    return JointState(
        stamp_ns=stamp_ns,
        seq=seq,
        position=[float(v) for v in q],
        gripper=position.gripper * GRIPPER_UNIT_MM * 1e-3,
        valid=valid,
        mode=mode_name(status.mode),
        encoder=list(encoder_fields(status, position)),
        applied_velocity=step_rates(applied[1:7]),
        applied_gripper_velocity=applied[7] * GRIPPER_COUNT_M_S,
        applied_kind=applied_kind,
        applied_seq=applied_seq,
    )


def arm_status(status: StatusFrame, *, stamp_ns: int, seq: int) -> ArmStatus:
    """The decoded status byte and message of one 0x350, with the message's meaning."""
    return ArmStatus(
        stamp_ns=stamp_ns,
        seq=seq,
        mode=mode_name(status.mode),
        mode_code=status.mode,
        msg_class=_CLASS_NAMES[status.msg_class],
        msg_code=status.msg_code,
        text=message_text(status.msg_class, status.msg_code),
    )


def can_frame(frame: Frame, stamp_ns: int, seq: int) -> CanFrame:
    """A frame as ``can/rx`` and ``can/tx`` carry it (``stamp_ns``: receive or send time)."""
    return CanFrame(
        stamp_ns=stamp_ns,
        seq=seq,
        id=frame.id & 0x7FF,
        data=frame.data,
        remote=frame.remote,
        dlc=min(frame.dlc, 8),
    )
