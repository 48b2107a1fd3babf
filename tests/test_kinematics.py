"""Forward/inverse kinematics and the Jacobian, by properties over sampled configurations."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from manus.config import DEFAULT_ARM, DEG, UNFOLDED_Q_DEG, ArmConfig
from manus.errors import KinematicsError
from manus.kinematics import (
    branch_of,
    fk,
    fk_batch,
    gripper_position,
    ik_all,
    ik_batch,
    ik_nearest,
    jacobian,
    jacobian_columns,
    joint_frames,
    wrap,
)
from manus.orientation import pose_matrix

angles = st.floats(-math.pi, math.pi, allow_nan=False)
configs = st.lists(angles, min_size=6, max_size=6).map(np.array)
UNFOLDED = np.radians(UNFOLDED_Q_DEG)


def test_unfolded_pose_matches_spec() -> None:
    # docs/protocol.md, Kinematics: the unfolded pose puts the gripper at about (208, 105, 200) mm.
    p = fk(UNFOLDED, DEFAULT_ARM)[:3, 3] * 1000
    assert p == pytest.approx([207.846, 105.0, 200.0], abs=1e-3)


def test_fk_matches_hand_expansion_at_zero() -> None:
    # All joints at zero: upper arm along +x, forearm and gripper straight up.
    T = fk(np.zeros(6), DEFAULT_ARM)
    cfg = ArmConfig()
    assert T[:3, 3] == pytest.approx([cfg.l2, cfg.l1, cfg.l3 + cfg.l4], abs=1e-12)


@given(configs)
def test_every_branch_reproduces_the_pose(q: np.ndarray) -> None:
    T = fk(q, DEFAULT_ARM)
    sols = ik_all(T, DEFAULT_ARM)
    assert 1 <= len(sols.q) <= 8
    for row in sols.q:
        assert np.abs(fk(row, DEFAULT_ARM) - T).max() < 1e-9


@given(configs)
def test_generating_configuration_is_among_the_branches(q: np.ndarray) -> None:
    # At the wrist singularity only q4 + q6 (or q4 - q6) is defined: any split is right.
    assume(abs(math.sin(q[4])) > 1e-6)
    sols = ik_all(fk(q, DEFAULT_ARM), DEFAULT_ARM)
    distance = np.abs(wrap(sols.q - q)).max(axis=1).min()
    assert distance < 1e-7


def test_batch_equals_scalar_and_round_trips() -> None:
    rng = np.random.default_rng(3)
    q = rng.uniform(-math.pi, math.pi, (2000, 6))
    T = fk_batch(q, DEFAULT_ARM)
    batch = ik_batch(T, DEFAULT_ARM)
    assert batch.valid.all()  # random configurations are generic: 8 branches each
    for i in range(len(q)):
        scalar = ik_all(T[i], DEFAULT_ARM)
        assert np.allclose(scalar.q, batch.q[i][batch.valid[i]], atol=1e-12)
    flat = batch.q.reshape(-1, 6)
    again = fk_batch(flat, DEFAULT_ARM).reshape(len(q), 8, 4, 4)
    assert np.abs(again - T[:, None]).max() < 1e-9


def test_fk_batch_equals_fk() -> None:
    rng = np.random.default_rng(4)
    q = rng.uniform(-4, 4, (50, 6))
    assert np.allclose(
        fk_batch(q, DEFAULT_ARM), np.array([fk(r, DEFAULT_ARM) for r in q]), atol=1e-14
    )


@given(configs)
def test_jacobian_equals_finite_differences(q: np.ndarray) -> None:
    J = jacobian(q, DEFAULT_ARM)
    h = 1e-6
    T0 = fk(q, DEFAULT_ARM)
    for j in range(6):
        dq = np.zeros(6)
        dq[j] = h
        Tp, Tm = fk(q + dq, DEFAULT_ARM), fk(q - dq, DEFAULT_ARM)
        v = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
        dR = (Tp[:3, :3] - Tm[:3, :3]) / (2 * h) @ T0[:3, :3].T
        w = np.array([dR[2, 1], dR[0, 2], dR[1, 0]])
        assert J[:3, j] == pytest.approx(v, abs=1e-7)
        assert J[3:, j] == pytest.approx(w, abs=1e-7)


@given(configs)
def test_closed_forms_equal_the_frames_and_the_jacobian(q: np.ndarray) -> None:
    # The controller's scalar twins of jacobian / fk, checked against the frames of the
    # DH product (joint axes z_i and origins p_i), other arm lengths too.
    arm = ArmConfig(l1=0.09, l2=0.41, l3=0.33, l4=0.15)
    for cfg in (DEFAULT_ARM, arm):
        frames = joint_frames(q, cfg)
        axes = np.array([T[:3, 2] for T in frames[:6]])
        origins = np.array([T[:3, 3] for T in frames])
        closed = np.array(jacobian_columns(q, cfg))  # (6 joints, 6 rows)
        assert closed[:, 3:] == pytest.approx(axes, abs=1e-12)
        linear = np.cross(axes, origins[-1] - origins[:6])
        assert closed[:, :3] == pytest.approx(linear, abs=1e-12)
        assert pytest.approx(jacobian(q, cfg), abs=1e-12) == closed.T
        assert gripper_position(q, cfg) == pytest.approx(origins[-1], abs=1e-12)
        assert gripper_position(q, cfg) == pytest.approx(fk(q, cfg)[:3, 3], abs=1e-12)


def test_nearest_branch_is_the_reference_branch_and_unwrapped() -> None:
    ref = UNFOLDED + np.array([0, 0, 0, 2 * math.pi, 0, -2 * math.pi])
    q = ik_nearest(fk(UNFOLDED, DEFAULT_ARM), ref, DEFAULT_ARM)
    assert q == pytest.approx(ref, abs=1e-9)


@given(configs)
def test_nearest_minimises_the_largest_joint_move(ref: np.ndarray) -> None:
    target = fk(UNFOLDED, DEFAULT_ARM)
    wide = ArmConfig(lower=tuple([-4 * math.pi] * 6), upper=tuple([4 * math.pi] * 6))
    best = ik_nearest(target, ref, wide, allow_singular=True)
    cost = np.abs(best - ref).max()
    for row in ik_all(target, DEFAULT_ARM).q:
        alt = ref + wrap(row - ref)
        assert cost <= np.abs(alt - ref).max() + 1e-12
    assert np.abs(fk(best, DEFAULT_ARM) - target).max() < 1e-9


def test_branch_of_agrees_with_ik_branch_labels() -> None:
    sols = ik_all(fk(UNFOLDED, DEFAULT_ARM), DEFAULT_ARM)
    for row, branch in zip(sols.q, sols.branch, strict=True):
        assert branch_of(row, DEFAULT_ARM) == tuple(branch)


def test_unreachable_pose_names_pose_and_reason() -> None:
    T = pose_matrix([2.0, 0.0, 0.0], (0.0, 0.0, 0.0))
    with pytest.raises(
        KinematicsError, match=r"pose \(2000.0, 0.0, 0.0\) mm is unreachable.*beyond"
    ) as e:
        ik_all(T, DEFAULT_ARM)
    assert e.value.reason == "unreachable"
    assert e.value.limit == pytest.approx(0.72)


def test_pose_inside_the_shoulder_offset_is_unreachable() -> None:
    # Wrist centre on the base axis: closer than L1 = 105 mm.
    T = pose_matrix([0.0, 0.0, 0.3 + 0.16], (0.0, 0.0, 0.0))
    with pytest.raises(KinematicsError, match="inside the shoulder offset") as e:
        ik_all(T, DEFAULT_ARM)
    assert e.value.reason == "unreachable"


def test_wrist_singularity_is_an_error_naming_joint_5() -> None:
    q = UNFOLDED.copy()
    q[4] = 0.0
    with pytest.raises(KinematicsError, match="wrist singularity: joint 5") as e:
        ik_nearest(fk(q, DEFAULT_ARM), q, DEFAULT_ARM)
    assert e.value.reason == "singular" and e.value.joint == 5
    # Exactly singular poses still solve when asked, with q4 = 0 by convention.
    sol = ik_nearest(fk(q, DEFAULT_ARM), q, DEFAULT_ARM, allow_singular=True)
    assert np.abs(fk(sol, DEFAULT_ARM) - fk(q, DEFAULT_ARM)).max() < 1e-9


def test_joint_limit_violation_names_joint_value_and_limit() -> None:
    cfg = ArmConfig(
        lower=tuple(-170 * DEG for _ in range(6)), upper=tuple(170 * DEG for _ in range(6))
    )
    q = UNFOLDED.copy()
    q[0] = 175 * DEG  # every branch of this pose needs joint 1 beyond 170 deg... or a far one
    T = fk(q, DEFAULT_ARM)
    sols = ik_all(T, cfg)
    if all(np.any(np.abs(r) > 170 * DEG) for r in sols.q):
        with pytest.raises(KinematicsError, match=r"joint \d at .* deg, limit .*170.0 deg") as e:
            ik_nearest(T, q, cfg)
        assert e.value.reason == "joint_limit"
    else:
        chosen = ik_nearest(T, q, cfg)
        assert np.all(np.abs(chosen) <= 170 * DEG)


def test_joint_5_limit_excludes_branches() -> None:
    cfg = ArmConfig(
        lower=(-2 * math.pi, -2 * math.pi, -2 * math.pi, -2 * math.pi, -0.5, -2 * math.pi),
        upper=(2 * math.pi, 2 * math.pi, 2 * math.pi, 2 * math.pi, 0.5, 2 * math.pi),
    )
    with pytest.raises(KinematicsError, match=r"joint 5 at -?\d+\.\d deg, limit -?28.6 deg") as e:
        ik_nearest(fk(UNFOLDED, DEFAULT_ARM), UNFOLDED, cfg)
    assert e.value.joint == 5
