"""The simulator's true state as a bus message (:class:`schemas.state.SimTruth`)."""

from __future__ import annotations

import numpy as np

from manus.kinematics import fk
from manus.orientation import matrix_to_ypr
from manus.protocol import JOINT_UNIT_DEG
from schemas.state import SimTruth
from services.simulator.arm import ArmModel, ArmState, motor_to_dh_deg


def make_truth(model: ArmModel, state: ArmState, t_ns: int, seq: int) -> SimTruth:
    """The truth of ``state`` at ``t_ns``.

    ``q_true`` are the belt-side joint angles (backlash, joint 1 scale error); ``q_reported``
    the DH angles of the encoder readings (motor angles quantised to 0.1 deg) at the same
    instant; the pose is the forward kinematics of ``q_true``; ``qd_true`` the motor speeds
    through the joint map's linear part (the belts' play aside).
    """
    qd = motor_to_dh_deg(state.speed_deg_s) - motor_to_dh_deg(np.zeros(6))
    q_true = np.radians(model.q_true_deg(state))
    counts = np.round(state.motor_deg / JOINT_UNIT_DEG) * JOINT_UNIT_DEG
    q_reported = np.radians(motor_to_dh_deg(counts))
    T = fk(q_true, model.config.arm)
    return SimTruth(
        stamp_ns=t_ns,
        seq=seq,
        q_true=[float(v) for v in q_true],
        q_reported=[float(v) for v in q_reported],
        gripper=state.gripper_mm / 1000.0,
        xyz=[float(v) for v in T[:3, 3]],
        ypr=[float(v) for v in matrix_to_ypr(T[:3, :3])],
        qd_true=[float(v) for v in np.radians(qd)],
    )
