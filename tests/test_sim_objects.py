"""The simulator holds objects: they rest on surfaces, closing jaws hold them (or they
slip), opening lets them fall to the surface below, and the truth records every contact."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from manus.errors import ConfigError
from manus.protocol import WARN_MOTOR_BLOCKED, MessageClass
from manus.scene import SceneError, default_scene, pose_matrix
from manus.shapes import coal_shape
from services.simulator.arm_bodies import distance
from services.simulator.camera_config import CameraConfig
from services.simulator.config import SimConfig
from services.simulator.core import SimCore
from services.simulator.grasp import JAW_HALF_WIDTH
from services.simulator.object_contacts import CONTACT_DEPTH
from services.simulator.object_world import ObjectWorld
from services.simulator.objects import SimObject, parse_objects
from services.simulator.scripted import joint_move
from tests.object_rig import CUP_LENGTH, CUP_RADIUS, TABLE_TOP, cup_centre, rig

SHAPES = {
    "box": st.tuples(*[st.floats(0.01, 0.2)] * 3),
    "sphere": st.tuples(st.floats(0.01, 0.1)),
    "cylinder": st.tuples(st.floats(0.01, 0.1), st.floats(0.01, 0.3)),
    "capsule": st.tuples(st.floats(0.01, 0.1), st.floats(0.01, 0.3)),
}


def world() -> ObjectWorld:
    return ObjectWorld(SimConfig(objects="none"), default_scene())


@st.composite
def placed(draw: st.DrawFn) -> SimObject:
    shape = draw(st.sampled_from(sorted(SHAPES)))
    size = draw(SHAPES[shape])
    xyz = [draw(st.floats(-0.6, 1.6)), draw(st.floats(-0.8, 0.8)), draw(st.floats(0.0, 1.6))]
    rpy = [draw(st.floats(-math.pi, math.pi)) for _ in range(3)]
    return SimObject("thing", "thing", shape, size, pose_matrix(xyz, rpy))


@given(placed())
@settings(max_examples=150)
def test_an_object_rests_upright_on_the_highest_surface_under_its_centre(obj: SimObject) -> None:
    x, y, z = (float(v) for v in obj.pose[:3, 3])
    yaw_axis = obj.pose[:2, 0] if np.hypot(*obj.pose[:2, 0]) > 1e-6 else obj.pose[:2, 1]
    w = world()
    w.add(obj)
    surface = w.supports.named(obj.support)
    assert obj.state == "resting"
    assert surface.holds(x, y) and surface.top <= z
    higher = [s for s in w.supports.surfaces if s.top > surface.top]
    assert not any(s.holds(x, y) and s.top <= z for s in higher)
    assert obj.pose[2, 3] == pytest.approx(surface.top + obj.half_height, abs=1e-12)
    assert obj.pose[:2, 3] == pytest.approx([x, y], abs=1e-12)
    assert obj.pose[:3, 2] == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)  # upright
    heading = math.atan2(obj.pose[1, 0], obj.pose[0, 0])
    assert math.remainder(heading - math.atan2(yaw_axis[1], yaw_axis[0]), math.tau) == (
        pytest.approx(0.0, abs=1e-9)
    )


def test_surfaces_of_the_default_scene() -> None:
    w = world()
    for xyz, surface, top in (
        ((0.95, -0.25, 0.9), "table", 0.74),
        ((0.6, -0.3, 1.2), "floor", 0.0),  # nothing beside the chair
        ((0.2, 0.0, 0.9), "thighs", 0.645),  # on the user's lap
        ((0.95, -0.25, 0.5), "floor", 0.0),  # under the table
    ):
        cup = SimObject("cup", "cup", "cylinder", (0.04, 0.1), pose_matrix(xyz, (0, 0, 0)))
        w.add(cup)
        assert (cup.support, cup.pose[2, 3]) == (surface, pytest.approx(top + 0.05)), xyz
        w.remove("cup")


def test_closing_jaws_hold_the_cup_and_it_follows_the_gripper() -> None:
    r = rig()
    r.close()
    truth = r.core.truth()
    (cup,) = truth.objects
    assert cup.held and cup.resting_on == "" and cup.slips == 0
    assert truth.gripper == pytest.approx(2 * CUP_RADIUS, abs=1e-9)  # the jaws stop on it
    grip = np.linalg.solve(r.gripper_pose(), r.cup_pose())
    assert grip[:3, 3] == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)
    for move in (joint_move(0, 4), joint_move(8, 0, 5), joint_move(0, 0, 0, 10, -10, 10)):
        for _ in range(6):
            r.pc.run_cycles(1, move)
            now = np.linalg.solve(r.gripper_pose(), r.cup_pose())
            assert np.abs(now - grip).max() < 1e-9
    assert np.linalg.norm(r.cup_pose()[:3, 3] - cup_centre()) > 0.05  # it went with the arm
    assert r.core.truth().gripper == pytest.approx(2 * CUP_RADIUS, abs=1e-9)


@pytest.mark.parametrize(
    ("offset", "held"),
    [
        ((0.0, -0.010, 0.0), True),  # 10 mm below the grasp point: within 15 mm
        ((0.0, -0.020, 0.0), False),  # 20 mm: slips
        ((0.0, 0.0, -0.014), True),  # deeper in the jaws by 14 mm
        ((0.0, 0.0, -0.030), False),  # 30 mm deeper: slips
        ((0.0, 0.0, 0.008), True),  # 8 mm nearer the fingertips
        ((0.012, 0.0, 0.0), True),  # off along the jaws: the fingers centre it
    ],
)
def test_a_grasp_off_by_more_than_the_tolerance_slips(
    offset: tuple[float, float, float], held: bool
) -> None:
    r = rig(offset)
    before = r.cup_pose()
    r.close(15)
    truth = r.core.truth()
    (cup,) = truth.objects
    assert (cup.held, cup.slips) == (held, 0 if held else 1)
    if held:
        assert truth.gripper == pytest.approx(2 * CUP_RADIUS, abs=1e-9)
        grip = np.linalg.solve(r.gripper_pose(), r.cup_pose())
        assert grip[:3, 3] == pytest.approx([0.0, offset[1], offset[2]], abs=1e-9)
    else:  # the fingers closed past it and it stayed on the table
        assert truth.gripper < 2 * CUP_RADIUS - 0.01
        assert cup.resting_on == "table"
        assert np.abs(r.cup_pose() - before).max() < 1e-12


@pytest.mark.parametrize("off", [0.003, -0.008])
def test_the_finger_that_reaches_an_off_centre_cup_first_pushes_it_without_contact(
    off: float,
) -> None:
    """A cup off the grasp point along the jaws: one finger reaches it first and slides it
    along the table until the other touches. That is the grasp, not a contact (the truth
    counted a finger 0.2 mm in the cup it closed on); the cup stays on the table, level."""
    r = rig((off, 0.0, 0.0))
    before = r.cup_pose()
    r.close(15)
    truth = r.core.truth()
    (cup,) = truth.objects
    assert cup.held and not truth.object_contacts and truth.contacts == 0
    grip = np.linalg.solve(r.gripper_pose(), r.cup_pose())
    assert grip[:3, 3] == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)
    moved = r.cup_pose()[:3, 3] - before[:3, 3]
    assert moved[2] == pytest.approx(0.0, abs=1e-9)  # along the table, not into it
    assert np.linalg.norm(moved) == pytest.approx(abs(off), abs=1e-6)


def test_a_cup_outside_the_jaws_is_not_grasped() -> None:
    r = rig((0.0, -(JAW_HALF_WIDTH + 0.005), 0.0))
    r.close(35)
    (cup,) = r.core.truth().objects
    assert not cup.held and cup.slips == 0 and r.core.truth().gripper < 0.001


def test_opening_releases_the_cup_which_falls_to_the_table() -> None:
    r = rig()
    r.close()
    r.pc.run_cycles(3, joint_move(0, 3))  # lift a little, still over the table
    r.pc.run_cycles(4, joint_move())  # and stop: it is released where it is then
    lifted = r.cup_pose()[:3, 3]
    assert lifted[2] > TABLE_TOP + CUP_LENGTH / 2 + 0.01
    heights = []
    for _ in range(12):
        r.pc.run_cycles(1, joint_move(gripper=10))
        heights.append(r.cup_pose()[2, 3])
    assert all(b <= a + 1e-6 for a, b in itertools.pairwise(heights))
    (cup,) = r.core.truth().objects
    assert not cup.held and cup.resting_on == "table"
    assert r.cup_pose()[:3, 3] == pytest.approx([*lifted[:2], TABLE_TOP + CUP_LENGTH / 2])
    assert r.cup_pose()[:3, 2] == pytest.approx([0.0, 0.0, 1.0])


def test_a_held_cup_meets_the_table_as_a_body_does() -> None:
    r = rig()
    r.close()
    r.pc.run_cycles(10, joint_move(0, -6))  # push it down into the table
    truth = r.core.truth()
    assert r.cup_pose()[2, 3] >= TABLE_TOP + CUP_LENGTH / 2 - CONTACT_DEPTH  # only touching
    assert truth.contacts > 0 and truth.contact == "cup/table"
    (contact,) = truth.object_contacts
    assert (contact.first, contact.second, contact.cls) == ("cup", "table", "environment")
    assert contact.ticks == truth.contacts and contact.depth == 0.0
    status = r.pc.cycles[-1].status
    assert (status.msg_class, status.msg_code) == (MessageClass.WARNING, WARN_MOTOR_BLOCKED)


def test_a_cup_taken_while_the_arm_still_settles_touches_the_table_without_contact() -> None:
    """The jaws close on the cup just after a one-cycle correction down: the drives' speed
    lag takes the arm on by micrometres after the grasp, the cup's bottom with it, into the
    table it stands on. Touching, as the contact record counts it (at most
    ``CONTACT_DEPTH`` deep): not a push that blocks the arm. (Live, nanometres of that
    tail blocked the arm for a tick: a ``cup/table`` contact under load.)"""
    r = rig()
    r.pc.run_cycles(5, joint_move(gripper=-10))  # the jaws 83 mm apart, the cup 70 wide
    r.pc.run_cycles(1, joint_move(0, -2, gripper=-10))  # a correction down: 10 deg/s
    r.pc.run_cycles(3, joint_move(gripper=-10))  # they reach the cup in the lag's tail
    r.pc.run_cycles(6, joint_move())
    truth = r.core.truth()
    (cup,) = truth.objects
    assert cup.held and truth.contacts == 0 and not truth.object_contacts
    sunk = TABLE_TOP + CUP_LENGTH / 2 - r.cup_pose()[2, 3]
    assert 1e-7 < sunk <= CONTACT_DEPTH  # the tail took it in, less than a contact's depth
    status = r.pc.cycles[-1].status
    assert (status.msg_class, status.msg_code) != (MessageClass.WARNING, WARN_MOTOR_BLOCKED)


def test_the_truth_gives_the_held_cups_distance_to_the_person() -> None:
    r = rig()
    assert r.core.truth().held_min_person is None  # nothing held yet
    r.close()
    truth = r.core.truth()
    scene = default_scene()
    cup_shape = coal_shape(r.cup.primitive(np.eye(4)))[0]
    person = min(
        distance(cup_shape, r.cup_pose(), *coal_shape(o.body))
        for o in scene.objects
        if o.cls == "person"
    )
    assert truth.held_min_person == pytest.approx(person, abs=1e-9)
    assert truth.held_clearance == pytest.approx(0.0, abs=1e-9)  # standing on the table
    assert truth.held_clearance_pair == "cup/table"


def test_a_finger_that_sweeps_through_a_free_cup_touches_it() -> None:
    r = rig()
    r.pc.run_cycles(6, joint_move(10))  # joint 1 swings the open jaws sideways
    (cup,) = r.core.truth().objects
    assert not cup.held and cup.resting_on == "table"
    touched = {(c.first, c.second, c.cls) for c in r.core.truth().object_contacts}
    assert ("finger_left", "cup", "object") in touched or ("finger_right", "cup", "object") in (
        touched
    )


def test_same_seed_same_objects() -> None:
    def run() -> list[object]:
        r = rig(seed=7)
        r.close()
        r.pc.run_cycles(5, joint_move(3, 3, 3))
        r.open()
        return [r.core.truth().objects, r.core.truth().object_contacts]

    assert run() == run()


def test_objects_added_and_removed_at_run_time() -> None:
    core = SimCore(SimConfig(objects="default", camera=CameraConfig(enabled=False)))
    assert [o.id for o in core.truth().objects] == ["cup", "bottle", "phone"]
    assert {o.resting_on for o in core.truth().objects} == {"table"}
    with pytest.raises(ConfigError, match="'cup': an object with that id is already there"):
        core.objects.add(SimObject("cup", "cup", "sphere", (0.03,), np.eye(4)))
    core.objects.remove("bottle")
    assert [o.id for o in core.truth().objects] == ["cup", "phone"]
    with pytest.raises(ConfigError, match=r"no object 'bottle' in the simulator \(objects: cup"):
        core.objects.remove("bottle")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("version: 1\nobjects:\n  - {id: cup, class: cup, shape: cone, xyz_mm: [0, 0, 0]}\n",
         "objs.yaml:3: objects[0].shape: unknown value 'cone'"),
        ("version: 1\nobjects:\n  - {id: cup, class: cup, shape: cylinder, radius_mm: 40,\n"
         "     xyz_mm: [0, 0, 0]}\n", "objs.yaml:3: objects[0].length_mm: missing field"),
        ("version: 1\nobjects:\n  - {id: a, class: cup, shape: sphere, radius_mm: 40,"
         " xyz_mm: [0, 0, 0]}\n  - {id: a, class: cup, shape: sphere, radius_mm: 4,"
         " xyz_mm: [0, 0, 0]}\n", "objs.yaml:4: objects[1].id: 'a' already on line 3"),
        ("version: 1\nobjects:\n  - {id: a, class: cup, shape: sphere, radius_mm: -4,"
         " xyz_mm: [0, 0, 0]}\n", "objs.yaml:3: objects[0].radius_mm: must be > 0, got -4"),
        ("version: 1\nobjects:\n  - {id: a, class: cup, shape: sphere, size_mm: [1, 2, 3],"
         " radius_mm: 4, xyz_mm: [0, 0, 0]}\n",
         "objs.yaml:3: objects[0].size_mm: not a field of a sphere"),
        ("version: 2\nobjects: []\n", "objs.yaml:1: version: this stack reads version 1"),
    ],
)  # fmt: skip
def test_objects_file_errors_name_the_file_line_and_field(text: str, message: str) -> None:
    with pytest.raises(SceneError) as caught:
        parse_objects(text, "objs.yaml")
    assert str(caught.value).startswith(message)
