"""The shipped URDF: generated from the DH table, loadable by Pinocchio, same FK as ours."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
from hypothesis import given
from hypothesis import strategies as st

from manus.config import DEFAULT_ARM, ArmConfig
from manus.kinematics import fk
from manus.urdf import build_urdf, shipped_urdf_path

MODEL = pin.buildModelFromUrdf(str(shipped_urdf_path()))
DATA = MODEL.createData()
FRAME = MODEL.getFrameId("gripper_frame")


def test_shipped_file_is_the_generated_one() -> None:
    assert shipped_urdf_path().read_text() == build_urdf(), (
        "regenerate with `manus kin urdf -o manus/data/manus.urdf`"
    )


def test_model_has_six_revolute_joints_with_the_configured_limits() -> None:
    cfg = ArmConfig()
    assert MODEL.nq == 6
    assert np.allclose(MODEL.lowerPositionLimit, cfg.lower)
    assert np.allclose(MODEL.upperPositionLimit, cfg.upper)
    assert np.allclose(MODEL.velocityLimit, cfg.max_speed)


@given(st.lists(st.floats(-math.pi, math.pi, allow_nan=False), min_size=6, max_size=6))
def test_pinocchio_fk_equals_ours(q: list[float]) -> None:
    pin.framesForwardKinematics(MODEL, DATA, np.array(q))
    assert np.abs(DATA.oMf[FRAME].homogeneous - fk(np.array(q), DEFAULT_ARM)).max() < 1e-12


def test_other_lengths_give_a_matching_model(tmp_path: object) -> None:
    cfg = ArmConfig(l1=0.0992, l2=0.3967, l3=0.3234, l4=0.15)
    model = pin.buildModelFromXML(build_urdf(cfg))
    data = model.createData()
    q = np.array([0.3, -0.2, 0.5, 1.0, -0.7, 0.2])
    pin.framesForwardKinematics(model, data, q)
    assert (
        np.abs(data.oMf[model.getFrameId("gripper_frame")].homogeneous - fk(q, cfg)).max() < 1e-12
    )
