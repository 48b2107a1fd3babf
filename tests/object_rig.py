"""A simulator with the gripper open around a cup standing on the default scene's table.

The arm starts (unfolded branch) with the gripper frame level, approaching along the
chair's x, its jaw axis along the chair's y, at ``offset`` (gripper frame: x jaw axis,
y up, z approach) [m] from the cup's centre; a :class:`ScriptedPc` drives it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from manus.config import ArmConfig
from manus.kinematics import ik_nearest
from manus.orientation import pose_matrix as ypr_pose
from manus.scene import default_scene, pose_matrix
from services.simulator.camera_config import CameraConfig
from services.simulator.config import SimConfig
from services.simulator.core import SimCore
from services.simulator.objects import SimObject
from services.simulator.scripted import ScriptedPc, joint_move

TABLE_TOP = 0.74
"""The default scene's table top [m] (chair frame)."""
CUP_RADIUS, CUP_LENGTH = 0.035, 0.12
CUP_XY = (0.88, -0.32)
"""Where the cup stands (chair frame) [m]."""
LEVEL = np.column_stack([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
"""Gripper frame axes in the chair frame: jaws along y, up, approach along x."""


def cup_centre() -> np.ndarray:
    """Where the cup's centre is once it rests on the table (chair frame) [m]."""
    return np.array([*CUP_XY, TABLE_TOP + CUP_LENGTH / 2.0])


def grasp_q_deg(offset: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> tuple[float, ...]:
    """DH angles [deg] that put the gripper frame at ``offset`` (gripper frame) from the
    cup's centre, level."""
    T = np.eye(4)
    T[:3, :3] = LEVEL
    T[:3, 3] = cup_centre() - LEVEL @ np.asarray(offset)
    arm = ArmConfig()
    near = np.radians((0.0, 30.0, -30.0, 0.0, -60.0, 0.0))
    q = ik_nearest(default_scene().in_base(T), near, arm)
    return tuple(float(v) for v in np.degrees(q))


@dataclass
class Rig:
    """The simulator, its scripted PC and the cup."""

    core: SimCore
    pc: ScriptedPc
    cup: SimObject

    def gripper_pose(self) -> np.ndarray:
        """The true gripper frame now, chair frame, (4, 4)."""
        truth = self.core.truth()
        base = ypr_pose(truth.xyz, (truth.ypr[0], truth.ypr[1], truth.ypr[2]))
        return np.asarray(default_scene().mount @ base)

    def cup_pose(self) -> np.ndarray:
        """The cup's true pose now, chair frame, (4, 4)."""
        found = next(o for o in self.core.truth().objects if o.id == "cup")
        return ypr_pose(found.xyz, (found.ypr[0], found.ypr[1], found.ypr[2]))

    def close(self, cycles: int = 12) -> None:
        """Close the jaws at 50 mm/s for ``cycles`` cycles."""
        self.pc.run_cycles(cycles, joint_move(gripper=-10))

    def open(self, cycles: int = 12) -> None:
        """Open the jaws at 50 mm/s for ``cycles`` cycles."""
        self.pc.run_cycles(cycles, joint_move(gripper=10))


def rig(offset: tuple[float, float, float] = (0.0, 0.0, 0.0), **overrides: object) -> Rig:
    """The simulator in joint mode, jaws open 90 mm around the cup (see the module
    docstring); ``overrides``: more simulator settings."""
    settings: dict[str, object] = {
        "start_pose": grasp_q_deg(offset),
        "start_gripper_mm": 90.0,
        "objects": "none",
        "camera": CameraConfig(enabled=False),
        **overrides,
    }
    core = SimCore(SimConfig().with_overrides(**settings))
    cup = SimObject(
        "cup",
        "cup",
        "cylinder",
        (CUP_RADIUS, CUP_LENGTH),
        pose_matrix(list(cup_centre()), (0, 0, 0)),
    )
    core.objects.add(cup)
    pc = ScriptedPc(core)
    pc.enter_joint_mode()
    return Rig(core, pc, cup)
