"""A gripper pose on the command line, in one order everywhere: ``X Y Z YAW PITCH ROLL``.

Position in mm, orientation in degrees, in the base frame; the angles mean
R = Rz(yaw) Ry(pitch) Rx(roll) (:mod:`manus.orientation`), the order messages and
``manus kin fk`` use (``xyz_mm`` then ``ypr_deg``, together ``pose``), so a pose printed
by one command pastes into any command that takes one (``manus kin ik``, and every later
command with a pose argument: declare it with :func:`add_pose_argument`, read it with
:func:`pose_values` and :func:`pose_from_values`).

Via-point files keep their own column order (yaw, roll, pitch: docs/protocol.md,
Orientation convention); only the command line uses this one.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from manus.orientation import matrix_to_ypr, pose_matrix

POSE_ORDER = ("X", "Y", "Z", "YAW", "PITCH", "ROLL")
"""The command line's pose, in order: position [mm], then yaw, pitch, roll [deg]."""

POSE_HELP = "gripper pose X Y Z [mm] YAW PITCH ROLL [deg] (base frame; as `manus kin fk` prints it)"
"""The help text of a pose argument."""

MEANINGS = (
    "gripper position x [mm], base frame",
    "gripper position y [mm], base frame",
    "gripper position z [mm], base frame",
    "yaw [deg]: turn about the base z, applied last (R = Rz(yaw) Ry(pitch) Rx(roll))",
    "pitch [deg]: turn about the base y",
    "roll [deg]: turn about the base x, applied first",
)
"""What each number of :data:`POSE_ORDER` is, with its unit."""


def finite_float(text: str) -> float:
    """An argparse ``type``: a finite number (NaN and infinities are usage errors)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid float value: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


def add_pose_argument(
    parser: argparse.ArgumentParser, flag: str = "pose", *, help_text: str = POSE_HELP
) -> None:
    """Declare a pose: six positional numbers (``flag`` without dashes) or an option of six
    (``--to-pose``), in :data:`POSE_ORDER`; read it back with :func:`pose_values`."""
    if flag.startswith("-"):
        parser.add_argument(flag, nargs=6, type=finite_float, metavar=POSE_ORDER, help=help_text)
        return
    for name, meaning in zip(POSE_ORDER, MEANINGS, strict=True):
        parser.add_argument(f"{flag}_{name.lower()}", type=finite_float, metavar=name, help=meaning)


def pose_values(args: argparse.Namespace, flag: str = "pose") -> list[float] | None:
    """The six numbers of the pose declared by :func:`add_pose_argument` (None: an option
    not given)."""
    if flag.startswith("-"):
        given = getattr(args, flag.lstrip("-").replace("-", "_"))
        return None if given is None else [float(v) for v in given]
    return [float(getattr(args, f"{flag}_{name.lower()}")) for name in POSE_ORDER]


def pose_from_values(values: list[float] | tuple[float, ...]) -> np.ndarray:
    """The 4x4 pose [m] of six numbers in :data:`POSE_ORDER` (mm, deg)."""
    x, y, z, yaw, pitch, roll = (float(v) for v in values)
    ypr = (math.radians(yaw), math.radians(pitch), math.radians(roll))
    return pose_matrix(np.array([x, y, z]) / 1000.0, ypr)


def pose_fields(T: np.ndarray, digits: int = 6) -> dict[str, list[float]]:
    """What a command prints of a pose ``T`` (4x4, m): ``xyz_mm``, ``ypr_deg`` and
    ``pose`` (the six numbers in :data:`POSE_ORDER`, to paste as a pose argument)."""
    xyz = (np.round(np.asarray(T[:3, 3], dtype=float) * 1000.0, digits) + 0.0).tolist()
    ypr = (np.round(np.degrees(matrix_to_ypr(T[:3, :3])), digits) + 0.0).tolist()
    return {"xyz_mm": xyz, "ypr_deg": ypr, "pose": xyz + ypr}
