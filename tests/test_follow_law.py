"""The follow law's pieces, without the arm: the scene as it sees it (frames, persons,
zones, reach), the standoff point kept clear of the person, the closer approach's cap,
backing away never slowed, and the closed-form gripper pose it solves with."""

from __future__ import annotations

import math

import numpy as np
import pytest

from manus.config import DEFAULT_ARM
from manus.errors import ConfigError
from manus.kinematics import fk, gripper_pose
from manus.scene import default_scene
from schemas.control import EndCause
from schemas.follow import CLOSE_SPEED_CAP, FollowGoal
from services.controller.config import ControllerConfig
from services.controller.follow_config import FollowConfig
from services.controller.follow_goal import settings as follow_settings
from services.controller.follow_law import Aim, FollowRun, Settings, standoff_point
from services.controller.follow_space import FollowSpace

SCENE = default_scene()
SPACE = FollowSpace(SCENE, DEFAULT_ARM)
CONFIG = ControllerConfig()
MOUTH = SPACE.point_to_base((0.083, 0.0, 1.192), "chair")
FORWARD = (1.0, 0.0, 0.0)  # the face's normal, chair x = base x (the mount does not turn)


def _settings(standoff: float = 0.06, clearance: float = 0.05, close: bool = False) -> Settings:
    return Settings(standoff, FORWARD, (0.0, 0.0, 0.06), 0.2, clearance, close)


def test_a_chair_point_is_moved_by_the_mount() -> None:
    mount = SCENE.mount
    p = SPACE.point_to_base((0.5, -0.2, 1.1), "chair")
    assert np.allclose(mount @ np.array([*p, 1.0]), [0.5, -0.2, 1.1, 1.0])
    assert SPACE.point_to_base((0.1, 0.2, 0.3), "base") == (0.1, 0.2, 0.3)


def test_the_person_distance_follows_a_moved_head() -> None:
    space = FollowSpace(SCENE, DEFAULT_ARM)
    d, name = space.person_distance(MOUTH)
    assert name == "head" and abs(d) < 0.003  # the mouth is on the head's front
    head = next(o for o in SCENE.objects if o.name == "head").body.pose.copy()
    head[0, 3] += 0.05  # the user leans 50 mm forward
    space.move_person("head", space.to_base @ head)
    d, _ = space.person_distance(MOUTH)
    depth = 0.110 - math.dist((0.083, 0.0, 1.192), (0.030, 0.0, 1.230))
    assert d == pytest.approx(-depth)  # the mouth where it was is now inside the head


def test_the_standoff_point_keeps_the_clearance() -> None:
    aim = Aim(MOUTH, (0.0, 0.0, 0.0), FORWARD)
    point = standoff_point(_settings(), aim, SPACE)
    assert point[0] - MOUTH[0] == pytest.approx(0.06)  # 60 mm out: outside the 50 mm
    inside = Aim(MOUTH, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))  # an axis along the face
    pushed = standoff_point(_settings(standoff=0.02, clearance=0.05), inside, SPACE)
    assert SPACE.person_distance(pushed)[0] >= 0.05  # pushed out along the axis


def test_the_standoff_grows_while_the_person_comes_at_the_arm() -> None:
    lean = _settings()._replace(lean_s=0.2)
    coming = Aim(MOUTH, (0.15, 0.05, 0.0), FORWARD)  # 150 mm/s toward the arm
    point = standoff_point(lean, coming, SPACE)
    assert point[0] - MOUTH[0] == pytest.approx(0.06 + 0.2 * 0.15)
    leaving = Aim(MOUTH, (-0.15, 0.0, 0.0), FORWARD)  # leaning back: no less than 60 mm
    assert standoff_point(lean, leaving, SPACE)[0] - MOUTH[0] == pytest.approx(0.06)
    assert standoff_point(_settings(), coming, SPACE)[0] - MOUTH[0] == pytest.approx(0.06)


def test_zones_and_reach_refuse_a_standoff_point() -> None:
    wheel = SPACE.point_to_base((-0.075, -0.44, 0.325), "chair")  # the right wheel's zone
    breach = SPACE.zone_breach(wheel)
    assert breach is not None and "right_wheel" in breach
    outside = SPACE.point_to_base((0.35, -0.2, 2.0), "chair")  # above the workspace
    breach = SPACE.zone_breach(outside)
    assert breach is not None and "workspace" in breach
    assert SPACE.zone_breach(MOUTH) is None
    assert SPACE.reach_breach((0.3, 0.2, 0.1), 8.0) is None
    far = SPACE.reach_breach((0.8, 0.2, 0.1), 8.0)
    assert far is not None and "beyond" in far
    inner = SPACE.reach_breach((0.0, 0.05, 0.3), 8.0)
    assert inner is not None and "offset" in inner


def test_a_standoff_point_out_of_reach_is_a_fault() -> None:
    q = [0.5, 0.3, -0.1, -0.9, -1.7, -0.2]
    run = FollowRun.start(_settings(), q, CONFIG)
    far = Aim((0.75, 0.3, 0.3), (0.0, 0.0, 0.0), FORWARD)  # in the workspace, too far
    step = run.step(far, SPACE, CONFIG)
    assert step.fault is not None and step.fault.cause == EndCause.OUT_OF_REACH
    wheel = SPACE.point_to_base((-0.075, -0.44, 0.325), "chair")
    step = run.step(Aim(wheel, (0.0, 0.0, 0.0), FORWARD), SPACE, CONFIG)
    assert step.fault is not None and step.fault.cause == EndCause.KEEP_OUT


def test_backing_away_is_never_slowed_and_closing_in_is() -> None:
    q = [0.5, 0.3, -0.1, -0.9, -1.7, -0.2]
    run = FollowRun.start(_settings(), q, CONFIG)
    start = run.point
    ahead = Aim((start[0] - 0.3, start[1], start[2]), (0.0, 0.0, 0.0), FORWARD)  # 240 mm in
    step = run.step(ahead, SPACE, CONFIG)
    assert step.fault is None
    assert math.dist(step.point, start) <= CONFIG.follow.accel * 0.06**2 + 1e-9  # a ramp
    back = FollowRun.start(_settings(), q, CONFIG)
    behind = Aim((start[0] - 0.06 + 0.1, start[1], start[2]), (0.0, 0.0, 0.0), FORWARD)
    for _ in range(5):
        step = back.step(behind, SPACE, CONFIG)
    assert back.velocity[0] > 0.1 - 1e-9  # at 100 mm/s and rising: not the 25 mm/s profile


def test_the_closer_approach_caps_motion_toward_the_target() -> None:
    q = [0.5, 0.3, -0.1, -0.9, -1.7, -0.2]
    run = FollowRun.start(_settings(standoff=0.03, clearance=0.02, close=True), q, CONFIG)
    target = (run.point[0] - 0.07, run.point[1], run.point[2])  # 70 mm away
    moving = Aim(target, (0.0, 0.05, 0.0), FORWARD)  # swaying sideways at 50 mm/s
    for _ in range(20):
        run.step(moving, SPACE, CONFIG)
        target = (target[0], target[1] + 0.05 * 0.06, target[2])
        moving = Aim(target, (0.0, 0.05, 0.0), FORWARD)
        assert math.hypot(*run.velocity) <= CLOSE_SPEED_CAP + 1e-9


def test_the_closed_form_pose_is_the_forward_kinematics() -> None:
    rng = np.random.default_rng(3)
    for _ in range(50):
        q = rng.uniform(-3.0, 3.0, 6)
        T = fk(q, DEFAULT_ARM)
        p, R = gripper_pose(q, DEFAULT_ARM)
        assert np.allclose(p, T[:3, 3]) and np.allclose(np.reshape(R, (3, 3)), T[:3, :3])


def test_settings_are_checked() -> None:
    with pytest.raises(ConfigError, match="max_speed"):
        FollowConfig(max_speed=0.5)
    with pytest.raises(ConfigError, match="model"):
        FollowConfig(model="quadratic")
    with pytest.raises(ConfigError, match="max_body_shift_m"):
        FollowConfig(max_body_shift_m=1.0)
    with pytest.raises(ConfigError, match="lean_margin_s"):
        FollowConfig(lean_margin_s=-0.1)


def test_only_a_target_on_a_person_grows_its_standoff() -> None:
    goal = FollowGoal(goal_id="g", source="mouth")
    assert follow_settings(goal, FollowConfig(), 0.05, on_person=True).lean_s == 0.2
    assert follow_settings(goal, FollowConfig(), 0.05, on_person=False).lean_s == 0.0
