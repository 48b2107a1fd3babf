"""Forward kinematics, geometric Jacobian and closed-form inverse kinematics.

Standard Denavit-Hartenberg (docs/protocol.md, Kinematics),
A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i):

    i  a   alpha  d   theta
    1  0   -90    0   q1
    2  L2    0    L1  q2
    3  0   +90    0   q3
    4  0   -90    L3  q4
    5  0   +90    0   q5
    6  0     0    L4  q6

The inverse kinematics is derived from this product (the thesis's printed IK
is wrong: docs/protocol.md, Corrections to the thesis).
With u = L2 c2 + L3 s23 and v = L2 s2 - L3 c23 the wrist centre is

    p_w = (c1 u - s1 L1,  s1 u + c1 L1,  -v)

so q1 follows from the horizontal distance (two shoulder branches, sign of u), (q2, q3)
from a planar two-link problem (two elbow branches), and (q4, q5, q6) from
R_36 = R_03^T R, a ZYZ-like spherical wrist (two wrist branches).

Modules: :mod:`~manus.kinematics.forward` (DH frames, FK, the Jacobian, NumPy),
:mod:`~manus.kinematics.closed_form` (the gripper position and the Jacobian's columns
with :mod:`math`, for the controller's cycle) and :mod:`~manus.kinematics.inverse`
(every IK branch, the nearest one within the limits). Every name is importable from
``manus.kinematics``.
"""

from __future__ import annotations

from manus.kinematics.closed_form import (
    Rot,
    Vec3,
    gripper_pose,
    gripper_position,
    jacobian_columns,
)
from manus.kinematics.forward import (
    dh_matrix,
    dh_table,
    fk,
    fk_batch,
    fk_position,
    jacobian,
    joint_frames,
)
from manus.kinematics.inverse import (
    BRANCHES,
    TWO_PI,
    IkBatch,
    IkSolutions,
    branch_of,
    ik_all,
    ik_batch,
    ik_nearest,
    is_wrist_singular,
    unwrap_near,
    wrap,
)

__all__ = [
    "BRANCHES",
    "TWO_PI",
    "IkBatch",
    "IkSolutions",
    "Rot",
    "Vec3",
    "branch_of",
    "dh_matrix",
    "dh_table",
    "fk",
    "fk_batch",
    "fk_position",
    "gripper_pose",
    "gripper_position",
    "ik_all",
    "ik_batch",
    "ik_nearest",
    "is_wrist_singular",
    "jacobian",
    "jacobian_columns",
    "joint_frames",
    "unwrap_near",
    "wrap",
]
