"""What the arm reports in a cycle: one snapshot of every position, as 0x350 and 0x360.

Both frames of a cycle carry the positions sampled at the same instant (T+20 ms), the
simulator's model of the 80C552 (docs/architecture.md, Time). Fields by situation:

- no move mode yet (no 0x374/0x371 since power-up): garbage (seeded noise or 0x7FFF);
- Cartesian mode: X, Y, Z [0.022 mm] and yaw, pitch, roll [0.1 deg] of the motor angles;
- otherwise: motor angles [0.1 deg], joints 4-6 replaced by their stale power-up values
  until they have been moved (docs/protocol.md, Thesis stale encoders);
- gripper opening [0.1 mm] (garbage too before a move mode).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from manus.protocol import (
    GRIPPER_UNIT_MM,
    JOINT_UNIT_DEG,
    Frame,
    FrameId,
    MessageClass,
    PositionFrame,
    StatusFrame,
    encode_position,
    encode_status,
)

I16_MAX = 32767


def to_counts(values: np.ndarray | list[float], unit: float) -> tuple[int, ...]:
    """Values quantised to ``unit`` (rounded to nearest), clamped to int16."""
    return tuple(max(-I16_MAX - 1, min(I16_MAX, round(float(v) / unit))) for v in np.ravel(values))


@dataclass(frozen=True)
class Snapshot:
    """One cycle's report, as the arm sampled it.

    Attributes:
        t_ns: sampling time (T+20 ms), also the send time of 0x350 [ns].
        mode: mode nibble.
        msg_class: message class of the status byte.
        msg_code: message code (byte 1).
        fields: the six position fields (see the module docstring).
        gripper: gripper field [0.1 mm] (or garbage).
    """

    t_ns: int
    mode: int
    msg_class: MessageClass
    msg_code: int
    fields: tuple[int, int, int, int, int, int]
    gripper: int

    def status_frame(self) -> Frame:
        """The 0x350 frame, stamped ``t_ns``."""
        a, b, c = self.fields[:3]
        body = StatusFrame(self.mode, self.msg_class, self.msg_code, (a, b, c))
        return Frame(FrameId.STATUS, encode_status(body), False, self.t_ns)

    def position_frame(self, t_ns: int) -> Frame:
        """The 0x360 frame, stamped ``t_ns`` (T+40 ms)."""
        a, b, c = self.fields[3:]
        return Frame(
            FrameId.POSITION, encode_position(PositionFrame((a, b, c), self.gripper)), False, t_ns
        )


def joint_fields(motor_deg: np.ndarray, stale_deg: tuple[float, ...] | None) -> tuple[int, ...]:
    """Motor angles as 0.1 deg fields; joints 4-6 replaced by ``stale_deg`` when given."""
    counts = to_counts(motor_deg, JOINT_UNIT_DEG)
    if stale_deg is None:
        return counts
    return counts[:3] + to_counts(list(stale_deg), JOINT_UNIT_DEG)


def gripper_field(gripper_mm: float) -> int:
    """Gripper opening as a 0.1 mm field."""
    return to_counts([gripper_mm], GRIPPER_UNIT_MM)[0]


def garbage_fields(rng: np.random.Generator, kind: str) -> tuple[int, ...]:
    """Seven meaningless fields (six positions and the gripper) before a move mode."""
    if kind == "max":
        return (I16_MAX,) * 7
    return tuple(int(v) for v in rng.integers(-I16_MAX - 1, I16_MAX + 1, size=7))
