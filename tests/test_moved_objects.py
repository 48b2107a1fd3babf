"""A scene object moved where a tracker sees it (the person's head): every check of the
collision model sees it there, within the bound the pairs kept stay right, and a model
built from it for held objects keeps it there."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from manus.collision import CollisionModel
from manus.config import DEFAULT_ARM, UNFOLDED_Q_DEG
from manus.held import HeldBody
from manus.moved_objects import MOVE_BOUND_M
from manus.scene import SceneError, default_scene
from manus.validity import ValidityChecker, checker_for

UNFOLDED = np.radians(UNFOLDED_Q_DEG)
MODEL = CollisionModel(default_scene(), DEFAULT_ARM)


def head_pose(model: CollisionModel) -> np.ndarray:
    assert model.scene is not None
    return next(o for o in model.scene.objects if o.name == "head").body.pose.copy()


def to_head(model: CollisionModel, q: np.ndarray) -> float:
    """The least margin of the pairs with the head [m] (Coal's)."""
    pairs = zip(model.margins(q), model.checks, strict=True)
    return min(float(m) for m, c in pairs if c.other == "head")


@pytest.mark.parametrize("axis", range(6))
def test_a_person_moved_within_the_bound_meets_no_body_its_pairs_left_out(axis: int) -> None:
    scene = default_scene()
    shift = np.zeros(3)
    shift[axis % 3] = MOVE_BOUND_M if axis < 3 else -MOVE_BOUND_M
    objects = []
    for obj in scene.objects:
        moved = obj
        if obj.name == "head":
            pose = obj.body.pose.copy()
            pose[:3, 3] += shift
            moved = dataclasses.replace(obj, body=dataclasses.replace(obj.body, pose=pose))
        objects.append(moved)
    built_there = CollisionModel(dataclasses.replace(scene, objects=tuple(objects)), DEFAULT_ARM)
    there = {c for c in built_there.checks if c.other == "head"}
    assert there <= {c for c in MODEL.checks if c.other == "head"}


def test_moving_an_object_moves_it_in_every_check() -> None:
    model = CollisionModel(default_scene(), DEFAULT_ARM)
    before = to_head(model, UNFOLDED)
    pose = head_pose(model)
    pose[:3, 3] += [0.1, -0.1, 0.0]
    assert model.move_object("head", pose) == pytest.approx(math.hypot(0.1, 0.1))
    probe = model.probe(UNFOLDED)
    assert to_head(model, UNFOLDED) < before - 0.05
    assert probe.best.margin <= to_head(model, UNFOLDED)
    with pytest.raises(SceneError, match="no scene object 'mouth'"):
        model.move_object("mouth", pose)


def test_a_turn_moves_the_far_side_of_the_object_by_its_radius_too() -> None:
    model = CollisionModel(default_scene(), DEFAULT_ARM)
    pose = head_pose(model)
    turned = pose.copy()
    c, s = math.cos(0.1), math.sin(0.1)
    turned[:3, :3] = pose[:3, :3] @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    assert model.move_object("head", turned) > 0.0
    assert model.move_object("head", turned) == 0.0  # already there


def test_a_model_built_for_held_objects_keeps_the_moved_head() -> None:
    model = CollisionModel(default_scene(), DEFAULT_ARM)
    pose = head_pose(model)
    pose[:3, 3] += [0.08, -0.08, 0.0]
    model.move_object("head", pose)
    cup = HeldBody("cup", "cup", "cylinder", (0.035, 0.1), (0.0, 0.0, 0.08), (0.0, 0.0, 0.0))
    holding = model.holding([cup])
    assert np.array_equal(holding.moved.poses["head"], pose)
    fresh = CollisionModel(default_scene(), DEFAULT_ARM).holding([cup])
    assert to_head(holding, UNFOLDED) < to_head(fresh, UNFOLDED) - 0.05


def test_the_fast_check_follows_a_moved_object_and_stays_below_coal() -> None:
    model = CollisionModel(default_scene(), DEFAULT_ARM)
    fast = checker_for(model)
    before = fast.margins(UNFOLDED)
    pose = head_pose(model)
    pose[:3, 3] += [0.2, -0.2, -0.2]  # the person leans to the upper arm
    model.move_object("head", pose)
    after = fast.margins(UNFOLDED)
    assert before.check.other != "head"
    assert after.check.other == "head"
    assert after.tight < before.tight
    assert after.tight <= to_head(model, UNFOLDED)
    rebuilt = ValidityChecker(model).margins(UNFOLDED)
    assert np.array_equal(after.free, rebuilt.free)
