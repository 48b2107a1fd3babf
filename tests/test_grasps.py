"""Grasps per object class (manus/grasps.py, manus/grasp_poses.py) and the pure stages of
the object steps (services/sequencer/object_stages.py, carry_stages.py, taskfile_objects.py)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from manus.config import DEFAULT_ARM, UNFOLDED_Q_DEG, ArmConfig
from manus.errors import KinematicsError
from manus.grasp_poses import blocked_by, grasps_of, tilt
from manus.grasps import Approach, GraspError, load_grasps, parse_grasps
from manus.kinematics import ik_nearest
from manus.orientation import matrix_to_ypr, pose_matrix
from manus.scene import default_scene
from schemas.goals import JointGoal, LineFrame, LineMotion
from schemas.objects import WorldObject
from schemas.planning import Trajectory
from schemas.sequencing import TaskStep
from services.sequencer.carry_stages import max_tilt, place_stages, tilt_problem
from services.sequencer.object_stages import (
    ObjectProblem,
    ObjectView,
    pick_plan,
    surface_under,
)
from services.sequencer.object_step import object_problems
from services.sequencer.pick_config import PickConfig
from services.sequencer.pick_stages import LIFT_OFF_M, pick_stages
from services.sequencer.taskfile import TaskFileError, parse_task_text

GOOD = """version: 1
classes:
  cup: {approach: side, height_mm: 8, pitch_deg: 15, yaw_step_deg: 15, yaw_span_deg: 75,
        pregrasp_mm: 80, lift_mm: 60, open_margin_mm: 25, squeeze_mm: 4, keep_level: true}
"""


def cup(x: float = 0.95, y: float = -0.2, yaw: float = 0.0, noise: float = 0.0) -> WorldObject:
    return WorldObject(
        id="cup", cls="cup", shape="cylinder", size=[0.04, 0.10], xyz=[x, y, 0.79],
        ypr=[yaw, noise, 0.0], confidence=0.9, stamp_ns=10**9, source="camera",
    )  # fmt: skip


def view(*objects: WorldObject, now_ns: int = 10**9) -> ObjectView:
    return ObjectView(
        {o.id: o for o in objects}, default_scene(), ArmConfig(), load_grasps(), PickConfig(),
        now_ns, 2.0, now_ns,
    )  # fmt: skip


def test_shipped_grasps_cover_cup_bottle_phone() -> None:
    classes = load_grasps()
    assert set(classes) >= {"cup", "bottle", "phone"}
    assert classes["cup"].approach == Approach.SIDE and classes["cup"].keep_level
    assert classes["phone"].approach == Approach.TOP
    assert classes["cup"].source.startswith("manus/data/grasps.yaml:")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (GOOD.replace("side", "sideways"), "t.yaml:3: classes.cup.approach: unknown value"),
        (GOOD.replace("pregrasp_mm: 80", "pregrasp_mm: 0"), "classes.cup.pregrasp_mm: must be > 0"),
        (
            GOOD.replace("pitch_deg: 15", "pitch_deg: 60"),
            "classes.cup.pitch_deg: must be in [0, 45]",
        ),
        (GOOD.replace("keep_level: true", "keep_level: 3"), "classes.cup.keep_level: must be true"),
        (GOOD.replace(", squeeze_mm: 4", ""), "classes.cup.squeeze_mm: missing field"),
        (GOOD.replace("version: 1", "version: 2"), "t.yaml:1: version: this stack reads version 1"),
    ],
)
def test_bad_grasps_file_names_line_and_field(text: str, message: str) -> None:
    with pytest.raises(GraspError) as err:
        parse_grasps(text, "t.yaml")
    assert message in str(err.value)


def test_side_grasps_come_in_from_the_shoulder_pitched_and_centred() -> None:
    how = parse_grasps(GOOD)["cup"]
    shoulder = np.array([0.35, -0.42, 1.0])
    grasps = grasps_of(cup(), how, shoulder)
    first = grasps[0]
    z = first.grasp[:3, 2]
    seen = np.array([0.95, -0.2]) - shoulder[:2]
    assert math.degrees(math.atan2(z[1], z[0])) == pytest.approx(
        math.degrees(math.atan2(seen[1], seen[0]))
    )
    assert math.degrees(math.asin(-z[2])) == pytest.approx(15.0)  # pitched down
    assert first.grasp[:3, 3] == pytest.approx([0.95, -0.2, 0.798])  # 8 mm above the centre
    assert first.pregrasp[:3, 3] == pytest.approx(first.grasp[:3, 3] - 0.08 * z)
    assert abs(first.grasp[2, 0]) < 1e-12  # jaw axis horizontal
    assert first.width == pytest.approx(0.08)
    assert len(grasps) == 11  # 0, +-15 ... +-75 deg


def test_noisy_lean_of_an_observed_cup_does_not_widen_it() -> None:
    how = parse_grasps(GOOD)["cup"]
    leaning = grasps_of(cup(noise=math.radians(3.0)), how, np.array([0.35, -0.42, 1.0]))
    assert leaning[0].width == pytest.approx(0.08)


def test_top_grasp_closes_across_the_phone() -> None:
    phone = WorldObject(
        id="phone", cls="phone", shape="box", size=[0.15, 0.075, 0.009], xyz=[1.0, 0.12, 0.745],
        ypr=[math.radians(20), 0.0, 0.0], confidence=0.9, stamp_ns=0, source="camera",
    )  # fmt: skip
    grasps = grasps_of(phone, load_grasps()["phone"], np.array([0.35, -0.42, 1.0]))
    assert len(grasps) == 2
    for g in grasps:
        assert g.grasp[:3, 2] == pytest.approx([0.0, 0.0, -1.0])
        assert g.width == pytest.approx(0.075)
        assert g.pregrasp[2, 3] > g.grasp[2, 3]


def test_another_object_in_the_way_blocks_a_grasp() -> None:
    how = parse_grasps(GOOD)["cup"]
    first = grasps_of(cup(), how, np.array([0.35, -0.42, 1.0]))[0]
    behind = first.pregrasp[:3, 3] - 0.05 * first.pregrasp[:3, 2]
    bottle = replace(cup(), id="bottle", xyz=[float(behind[0]), float(behind[1]), 0.85])
    assert blocked_by(first, [bottle]) == "bottle"
    far = replace(bottle, xyz=[0.95, 0.3, 0.85])
    assert blocked_by(first, [far]) == ""


def test_pick_plan_names_the_object_and_the_reason() -> None:
    with pytest.raises(ObjectProblem, match=r"unknown object 'mug' \(the world model holds: cup\)"):
        pick_plan(view(cup()), "mug")
    with pytest.raises(ObjectProblem, match="perception lost: no update of the world model"):
        pick_plan(replace(view(cup(), now_ns=4 * 10**9), world_ns=10**9), "cup")
    seen_long_ago = replace(cup(), stamp_ns=0)
    stale = replace(view(seen_long_ago, now_ns=6 * 10**9), world_ns=6 * 10**9)
    with pytest.raises(ObjectProblem, match=r"object 'cup' \(cup\) cannot be picked: not seen"):
        pick_plan(stale, "cup")
    wide = replace(cup(), size=[0.06, 0.10])
    with pytest.raises(ObjectProblem, match=r"120 mm wide .* wider than the gripper opens"):
        pick_plan(view(wide), "cup")
    ring = [
        replace(cup(), id=f"b{k}", xyz=[0.95 + 0.12 * math.cos(a), -0.2 + 0.12 * math.sin(a), 0.85])
        for k, a in enumerate(np.linspace(-math.pi, math.pi, 12, endpoint=False))
    ]
    with pytest.raises(ObjectProblem, match=r"every grasp pose of object 'cup' \(cup\) collides"):
        pick_plan(view(cup(), *ring), "cup")


def test_pick_stages_in_order_and_table_as_touch_object() -> None:
    v = view(cup())
    plan = pick_plan(v, "cup")
    assert plan.surface == "table"
    stages = pick_stages(plan, plan.grasps[0], v)
    labels = [s.label for s in stages]
    assert labels == [
        "open", "pre-grasp", "approach", "close", "attach", "lift off", "lift",
        "clear of the surface", "retreat",
    ]  # fmt: skip
    assert stages[0].opening == pytest.approx(0.09)  # 80 mm + 25, at most the gripper's 90
    assert stages[3].holds == pytest.approx(0.08)
    assert stages[4].touch_objects == ("table",)
    approach = stages[2].motion(np.zeros(6))  # type: ignore[misc]
    assert isinstance(approach, LineMotion) and approach.frame == LineFrame.TOOL
    assert approach.xyz == pytest.approx([0.0, 0.0, 0.08])


def test_the_lift_off_raises_the_object_on_the_shoulder_alone() -> None:
    v = view(cup())
    plan = pick_plan(v, "cup")
    tried = 0
    for grasp in plan.grasps[:4]:
        try:
            q = ik_nearest(v.in_base(grasp.grasp), np.radians(UNFOLDED_Q_DEG), DEFAULT_ARM)
        except KinematicsError:
            continue  # out of reach or beyond a limit: not a grasp the pick would use
        stages = {s.label: s for s in pick_stages(plan, grasp, v)}
        goal = stages["lift off"].motion(q)  # type: ignore[misc]
        assert isinstance(goal, JointGoal)
        moved = np.array(goal.joints) - q
        assert np.count_nonzero(moved) == 1 and moved[1] != 0.0  # joint 2 only
        before, after = v.gripper(q), v.gripper(np.array(goal.joints))
        assert after[2, 3] - before[2, 3] == pytest.approx(LIFT_OFF_M, abs=2e-4)
        # every point of the cup's bottom (35 mm around the grasp point) rises
        for angle in np.linspace(0.0, 2.0 * np.pi, 12, endpoint=False):
            p = np.array([0.035 * np.cos(angle), 0.035 * np.sin(angle), 0.0, 1.0])
            assert (after @ p)[2] - (before @ p)[2] > 0.5 * LIFT_OFF_M
        tried += 1
    assert tried >= 2
    # from no surface (held in the air) no lift off
    plan_air = replace(plan, surface="")
    assert "lift off" not in [s.label for s in pick_stages(plan_air, plan.grasps[0], v)]


def test_surface_under_allows_perception_noise_either_way() -> None:
    scene = default_scene()
    for dz in (-0.008, 0.0, 0.008):
        assert surface_under(scene, cup(), 0.74 + dz) == "table"
    assert surface_under(scene, cup(), 0.80) == ""


def held_cup(v: ObjectView, q: np.ndarray) -> WorldObject:
    T = np.linalg.solve(v.gripper(q), pose_matrix(np.array([0.95, -0.2, 0.85]), (0.0, 0.0, 0.0)))
    return replace(
        cup(), xyz=[float(x) for x in T[:3, 3]],
        ypr=[float(a) for a in matrix_to_ypr(T[:3, :3])], link="gripper_frame",
    )  # fmt: skip


def test_place_refuses_a_leaning_pose_and_a_pose_in_the_air() -> None:
    v = view(cup())
    q = np.radians([0.0, 30.0, -30.0, 0.0, -60.0, 0.0])
    held = held_cup(v, q)
    with pytest.raises(ObjectProblem, match=r"cannot be placed leaning 20\.0 deg"):
        place_stages(v, held, q, [0.9, -0.2, 0.79, 0.0, math.radians(20), 0.0], "")
    with pytest.raises(ObjectProblem, match=r"nothing to put it on at \(900, -200, 900\) mm"):
        place_stages(v, held, q, [0.9, -0.2, 0.90, 0.0, 0.0, 0.0], "")
    with pytest.raises(ObjectProblem, match="no surface 'desk'"):
        place_stages(v, held, q, None, "desk")
    stages = place_stages(v, held, q, [0.9, -0.2, 0.79, 0.0, 0.0, 0.0], "")
    assert [s.label for s in stages][:3] == ["carry", "set down", "lower"]
    assert stages[1].touch_objects == ("table",)


def test_tilt_along_a_trajectory_is_judged_on_the_held_object() -> None:
    v = view(cup())
    q0 = np.radians([0.0, 30.0, -30.0, 0.0, -60.0, 0.0])
    held = held_cup(v, q0)
    q1 = q0 + np.radians([0.0, 0.0, 0.0, 0.0, 20.0, 0.0])  # the wrist pitches 20 deg
    traj = Trajectory(
        times=[0.0, 2.0], positions=[list(q0), list(q1)], velocities=[[0.0] * 6, [0.0] * 6]
    )
    up = np.linalg.solve(v.gripper(q0)[:3, :3], [0.0, 0.0, 1.0])  # upright at the start
    worst, when = max_tilt(v, traj, up)
    assert math.degrees(worst) == pytest.approx(20.0, abs=0.01) and when == pytest.approx(2.0)
    problem = tilt_problem(v, held, traj, "carry")
    assert "carry: the cup would tilt 20.0 deg at 2.00 s (it is kept within 10 deg" in problem
    still = Trajectory(
        times=[0.0, 2.0], positions=[list(q0), list(q0)], velocities=[[0.0] * 6, [0.0] * 6]
    )
    assert tilt_problem(v, held, still, "carry") == ""
    assert tilt(np.eye(3)) == 0.0


def test_task_file_object_steps() -> None:
    task = parse_task_text(
        '[[step]]\npick = "cup"\n[[step]]\nplace = "cup"\nat = [950, -150, 790, 0, 0, 0]\n'
        '[[step]]\nplace = "cup"\non = "table"\n[[step]]\ngive = "cup"\n'
    )
    kinds = [(s.kind, s.object) for s in task.steps]
    assert kinds == [("pick", "cup"), ("place", "cup"), ("place", "cup"), ("give", "cup")]
    assert task.steps[1].at == pytest.approx([0.95, -0.15, 0.79, 0.0, 0.0, 0.0])
    assert task.steps[2].surface == "table"
    with pytest.raises(TaskFileError) as err:
        parse_task_text(
            '[[step]]\nplace = "cup"\nat = [1, 2]\n[[step]]\npick = 3\n[[step]]\nplace = "cup"\n',
            source="t.toml",
        )
    assert err.value.errors == [
        "t.toml:3: step 1 (place): at takes 6 numbers (X Y Z [mm], YAW PITCH ROLL [deg]), "
        "got [1, 2]",
        't.toml:5: step 2 (pick): pick takes an object\'s id (a name, e.g. "cup"), got 3',
        "t.toml:7: step 3 (place): a place step needs one of at = [X, Y, Z, YAW, PITCH, ROLL], "
        "on = SURFACE or back = true",
    ]


def test_task_file_place_back_and_give_at() -> None:
    task = parse_task_text(
        '[[step]]\npick = "cup"\n[[step]]\ngive = "cup"\nat = [310, -50, 1090, 150, 0, 0]\n'
        '[[step]]\nplace = "cup"\nback = true\n'
    )
    give, place = task.steps[1], task.steps[2]
    assert give.at == pytest.approx([0.31, -0.05, 1.09, math.radians(150), 0.0, 0.0])
    assert place.back and place.at is None and not place.surface
    assert object_problems(place) == [] and object_problems(give) == []
    with pytest.raises(TaskFileError) as err:
        parse_task_text(
            '[[step]]\nplace = "cup"\nback = 1\n[[step]]\nplace = "cup"\nback = true\n'
            'on = "table"\n',
            source="t.toml",
        )
    assert err.value.errors == [
        "t.toml:3: step 1 (place): back takes true (put it back where the pick took it), got 1",
        "t.toml:5: step 2 (place): a place step needs one of at = [X, Y, Z, YAW, PITCH, ROLL], "
        "on = SURFACE or back = true",
    ]
    assert object_problems(TaskStep(kind="give", object="cup", back=True)) == [
        "back is for a place step, not give"
    ]
