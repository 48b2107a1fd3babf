"""Goals: named poses (the file and its errors), goals written in task files, goal
states (every valid IK branch, tolerances, zones, the work area) and the refusals."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from manus.collision import CollisionModel
from manus.config import DEFAULT_ARM, FOLDED_Q_DEG, UNFOLDED_Q_DEG
from manus.goal_spec import GoalSpecError, goal_from_spec
from manus.kinematics import fk
from manus.named_poses import NamedPoseError, named_poses, parse_poses
from manus.orientation import pose_matrix
from manus.scene import default_scene
from schemas.goals import INTERPOLATIONS, JointGoal, LineMotion, NamedGoal, ObjectGoal, PoseGoal
from schemas.planning import Interpolation
from services.planner.errors import PlanningError
from services.planner.goal_planner import validity_of
from services.planner.goal_states import goal_states
from services.planner.goal_target import Target, resolve_target
from services.planner.work_area import STEP_M, WorkArea, gripper_positions

UNFOLDED = np.radians(UNFOLDED_Q_DEG)
MODEL = CollisionModel(default_scene(), DEFAULT_ARM)
EXACT = validity_of(MODEL)[1]
WORK = WorkArea(DEFAULT_ARM)


def states(T: np.ndarray, **tolerances: float | bool) -> np.ndarray:
    target = Target("test", pose=T, **tolerances)  # type: ignore[arg-type]
    return goal_states(target, UNFOLDED, DEFAULT_ARM, EXACT, MODEL.scene, 1, WORK)


def refusal(T: np.ndarray) -> tuple[str, str]:
    with pytest.raises(PlanningError) as info:
        states(T)
    return info.value.error.reason, info.value.error.message


def test_the_named_poses_are_the_fold_poses_and_the_shipped_file() -> None:
    poses = named_poses("")
    assert set(poses) >= {"home", "drink", "folded", "unfolded"}
    assert poses["folded"].joints == pytest.approx(np.radians(FOLDED_Q_DEG))
    assert poses["home"].joints == pytest.approx(UNFOLDED)
    assert poses["drink"].source.startswith("manus/data/poses.yaml:")
    # The shipped drink pose keeps every clearance in the default scene.
    assert EXACT.margins(np.array(poses["drink"].joints)).tightest > 0.05


def test_a_user_poses_file_adds_and_redefines(tmp_path: Path) -> None:
    file = tmp_path / "poses.yaml"
    file.write_text(
        "version: 1\nposes:\n"
        "  - {name: drink, joints_deg: [0, 20, -20, 0, -60, 0]}\n"
        "  - {name: shelf, xyz_mm: [450, 150, 250], ypr_deg: [0, 90, 0], free_axis: true,\n"
        "     position_tolerance_mm: 5, angle_tolerance_deg: 5}\n"
    )
    poses = named_poses(str(file))
    assert poses["drink"].joints == pytest.approx(np.radians([0, 20, -20, 0, -60, 0]))
    shelf = poses["shelf"]
    assert shelf.xyz == pytest.approx((0.45, 0.15, 0.25)) and shelf.free_axis
    assert shelf.position_tolerance == pytest.approx(0.005)
    assert shelf.source == f"{file}:4"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("version: 2\nposes: []\n", "<t>:1: version: this stack reads version 1, got 2"),
        (
            "version: 1\nposes:\n  - {name: folded, joints_deg: [0, 0, 0, 0, 0, 0]}\n",
            "<t>:3: poses[0].name: 'folded' is the arm's own fold pose and cannot be redefined",
        ),
        (
            "version: 1\nposes:\n  - {name: a, joints_deg: [0, 0, 0]}\n",
            "<t>:3: poses[0].joints_deg: must be a list of 6 numbers",
        ),
        (
            "version: 1\nposes:\n  - {name: a, xyz_mm: [1, 2, 3]}\n",
            "<t>:3: poses[0].ypr_deg: missing field (a gripper pose needs it)",
        ),
        (
            "version: 1\nposes:\n  - {name: a, joints_deg: [0, 0, 0, 0, 0, 0], free_axis: true}\n",
            "<t>:3: poses[0].free_axis: only a gripper pose (xyz_mm) takes it",
        ),
        (
            "version: 1\nposes:\n  - {name: a, xyz_mm: [1, 2, 3], ypr_deg: [0, 0, 0],\n"
            "     angle_tolerance_deg: 40}\n",
            "<t>:4: poses[0].angle_tolerance_deg: must be <= 28, got 40",
        ),
        (
            "version: 1\nposes:\n  - {name: a, joints_deg: [0, 0, 0, 0, 0, 0]}\n"
            "  - {name: a, joints_deg: [0, 0, 0, 0, 0, 0]}\n",
            "<t>:4: poses[1].name: 'a' already defined at <t>:3",
        ),
        (
            "version: 1\nposes:\n  - {name: a, colour: red}\n",
            "<t>:3: poses[0].colour: unknown field",
        ),
    ],
)
def test_a_bad_poses_file_names_the_line_and_the_field(text: str, message: str) -> None:
    with pytest.raises(NamedPoseError) as info:
        parse_poses(text, "<t>")
    assert str(info.value).startswith(message)


def test_goals_as_a_task_file_writes_them() -> None:
    assert goal_from_spec("drink") == NamedGoal(name="drink")
    pose = goal_from_spec({"pose": [560, 100, -150, 0, 90, 0], "free_axis": True, "seed": 3})
    assert isinstance(pose, PoseGoal) and pose.tolerance.free_axis and pose.search.seed == 3
    assert pose.xyz == pytest.approx([0.56, 0.1, -0.15])
    assert pose.ypr == pytest.approx([0.0, math.pi / 2, 0.0])
    obj = goal_from_spec({"object": "table", "pose": [-250, -300, 130, 0, 90, 0]})
    assert isinstance(obj, ObjectGoal) and obj.name == "table"
    line = goal_from_spec({"approach": -80})
    assert isinstance(line, LineMotion) and line.frame == "tool" and line.xyz[2] == -0.08
    joints = goal_from_spec({"joints": [30, 20, -40, 10, -50, 0]})
    assert isinstance(joints, JointGoal)
    assert tuple(Interpolation) == INTERPOLATIONS


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ({}, "give exactly one of named, pose"),
        ({"pose": [1, 2, 3]}, "pose: a list of 6 numbers"),
        ({"pose": [1, 2, 3, 4, 5, 6], "named": "x"}, "give exactly one of"),
        ({"approach": 40, "free_axis": True}, "free_axis: not an option of a approach goal"),
        ({"named": "drink", "colour": 1}, "unknown key 'colour'"),
        (
            {"pose": [0, 0, 0, 0, 0, 0], "tolerance_mm": 500},
            "PoseGoal/1.tolerance.position: 0.5 is above the maximum 0.1",
        ),
        ({"joints": [0, 0, 0, 0, 0, "x"]}, "joints: a finite number, got 'x'"),
    ],
)
def test_a_badly_written_goal_names_the_key(spec: dict[str, object], message: str) -> None:
    with pytest.raises(GoalSpecError, match=message):
        goal_from_spec(spec)


def test_every_valid_ik_branch_is_a_goal_state_nearest_first() -> None:
    T = pose_matrix(np.array([0.56, 0.10, -0.15]), (0.0, math.pi / 2, 0.0))
    found = states(T)
    assert 1 <= len(found) <= 8
    distances = np.linalg.norm(found - UNFOLDED, axis=1)
    assert np.all(np.diff(distances) >= 0.0)
    for q in found:
        np.testing.assert_allclose(fk(q, DEFAULT_ARM), T, atol=1e-9)
        assert EXACT.margins(q).tightest >= 0.0
        assert (q >= DEFAULT_ARM.lower_array).all() and (q <= DEFAULT_ARM.upper_array).all()


def test_a_free_axis_and_tolerances_give_more_goal_states_within_them() -> None:
    T = pose_matrix(np.array([0.55, 0.05, -0.12]), (0.0, math.pi, 0.0))
    plain, free = states(T), states(T, free_axis=True)
    assert len(free) > len(plain)
    for q in free:  # the approach axis is the goal's, the position too
        Tq = fk(q, DEFAULT_ARM)
        np.testing.assert_allclose(Tq[:3, 3], T[:3, 3], atol=1e-9)
        np.testing.assert_allclose(Tq[:3, 2], T[:3, 2], atol=1e-9)
    loose = states(T, position_tolerance=0.01, angle_tolerance=math.radians(5))
    for q in loose:
        Tq = fk(q, DEFAULT_ARM)
        assert np.linalg.norm(Tq[:3, 3] - T[:3, 3]) <= 0.01 + 1e-12
        turn = math.acos(min(1.0, (np.trace(Tq[:3, :3].T @ T[:3, :3]) - 1) / 2))
        assert turn <= math.radians(5) + 1e-9


def test_refusals_name_the_reason() -> None:
    reason, message = refusal(pose_matrix(np.array([0.6, 0.1, -0.24]), (0.0, math.pi, 0.0)))
    assert reason == "goal_collision" and "table (environment: needs 15 mm)" in message
    reason, message = refusal(pose_matrix(np.array([-0.3, -0.05, -0.6]), (0.0, math.pi, 0.0)))
    assert reason == "zone" and "keep-out zone 'right_wheel'" in message
    reason, message = refusal(pose_matrix(np.array([0.2, -0.9, 0.0]), (0.0, math.pi / 2, 0.0)))
    assert reason == "zone" and "outside the keep-in zone 'workspace'" in message
    reason, message = refusal(pose_matrix(np.array([0.83, 0.35, 0.0]), (0.0, math.pi / 2, 0.0)))
    assert reason == "unreachable" and "beyond the arm's reach" in message
    reason, message = refusal(pose_matrix(np.array([0.29, 0.17, -0.75]), (0.0, math.pi, 0.0)))
    assert reason == "zone" and "400.0 mm below the work area's floor (z -350 mm)" in message


def test_targets_of_named_object_and_joint_goals() -> None:
    poses = named_poses("")
    drink = resolve_target(NamedGoal(name="drink"), MODEL.scene, poses)
    assert drink.joints is not None and "manus/data/poses.yaml" in drink.label
    table = resolve_target(
        ObjectGoal(name="table", xyz=[-0.25, -0.3, 0.13], ypr=[0.0, math.pi / 2, 0.0]),
        MODEL.scene,
        poses,
    )
    assert table.pose is not None
    np.testing.assert_allclose(table.pose[:3, 3], [0.5, 0.12, -0.15], atol=1e-12)
    with pytest.raises(PlanningError, match="'cupboard' is not an object of the scene"):
        resolve_target(
            ObjectGoal(name="cupboard", xyz=[0.0] * 3, ypr=[0.0] * 3), MODEL.scene, poses
        )
    with pytest.raises(PlanningError, match="unknown named pose 'kitchen'"):
        resolve_target(NamedGoal(name="kitchen"), MODEL.scene, poses)
    beyond = JointGoal(joints=[0.0, 0.5, -0.5, 0.0, math.radians(-130), 0.0])
    with pytest.raises(PlanningError, match=r"joint 5 at -130\.00 deg is beyond its limit"):
        goal_states(
            resolve_target(beyond, MODEL.scene, poses),
            UNFOLDED,
            DEFAULT_ARM,
            EXACT,
            MODEL.scene,
            1,
            WORK,
        )


def test_the_work_area_gripper_positions_are_the_forward_kinematics() -> None:
    Q = np.random.default_rng(0).uniform(-3.0, 3.0, (50, 6))
    xyz = np.stack(gripper_positions(Q, DEFAULT_ARM), axis=1)
    np.testing.assert_allclose(xyz, [fk(q, DEFAULT_ARM)[:3, 3] for q in Q], atol=1e-12)
    area, elbow = WORK.margins(np.array([UNFOLDED, [0.0, 0.0, math.pi / 2, 0.0, 0.3, 0.0]]))
    assert area[0] > 0.1 and elbow[0] > 0.0 and elbow[1] < 0.0
    # A motion down through the floor is refused; a motion above it is not.
    low = np.radians([0, 90, 0, 0, 0, 0])
    assert fk(low, DEFAULT_ARM)[2, 3] < DEFAULT_ARM.work_floor_z
    assert not WORK.motion(UNFOLDED, low, 0.0)
    assert WORK.motion(UNFOLDED, np.radians([30, 30, -30, 0, -60, 0]), 0.0)


def test_the_compiled_work_area_agrees_with_dense_samples() -> None:
    rng = np.random.default_rng(1)
    Q = rng.uniform(DEFAULT_ARM.lower_array, DEFAULT_ARM.upper_array, (200, 6))
    area, elbow = WORK.margins(Q)
    tight = [WORK.tightest(q) for q in Q]
    np.testing.assert_allclose(tight, np.minimum(area, elbow * DEFAULT_ARM.l3), atol=1e-12)
    # A motion the bisection proves keeps the floor at 400 samples along it; it refuses
    # some, and those it refuses come within a step of the floor or cross it.
    proven = refused = 0
    for qa, far in zip(Q[:100], Q[100:], strict=True):
        qb = qa + 0.3 * (far - qa)
        dense = WORK.margins(qa + np.linspace(0.0, 1.0, 400)[:, None] * (qb - qa))
        floor = 0.01
        if WORK.motion(qa, qb, floor):
            proven += 1
            assert dense[0].min() >= floor - 1e-9 and dense[1].min() >= 0.0
        else:
            refused += 1
            assert dense[0].min() < floor + STEP_M or dense[1].min() < 1e-6
    assert proven > 10 and refused > 10
