"""Attached objects: the world model attaches a grasped object to the gripper and detaches
it where it is, each a versioned diff every follower applies the same way; perception
neither moves, removes nor stales a held object; the planner answers ``planner/attach``
(refusals name the object and the reason) and its collision model carries the held
cup, which keeps the person's clearance like any link of the arm."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from manus.collision import CollisionModel
from manus.config import DEFAULT_ARM, UNFOLDED_Q_DEG
from manus.held import HeldBody
from manus.kinematics import fk, ik_nearest
from manus.orientation import pose_matrix
from manus.scene import default_scene
from manus.urdf import GRIPPER_FRAME
from manus.validity import checker_for
from manus.viapoints import parse_viapoints
from manus.world import ARM, WorldModel
from manus.world_follower import WorldFollower
from schemas import endpoints as ep
from schemas.objects import (
    AttachReply,
    AttachRequest,
    ObservedObject,
    Perception,
    WorldUpdate,
)
from schemas.planning import PlanRequest, ViaPointPath
from services.planner.core import PlannerCore
from services.planner.wiring import WIRING as PLANNER

S = 1_000_000_000
SCENE = default_scene()
UNFOLDED = np.radians(UNFOLDED_Q_DEG)
HEAD = np.array([-0.02, 0.0, 1.23])
"""The default scene's head centre (chair frame) [m]; its radius is 110 mm."""
FACING_HEAD = np.column_stack([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]])
"""Gripper axes in the chair frame: jaws along y, approach along -x (at the user)."""
CUP = HeldBody("cup", "cup", "cylinder", (0.04, 0.1), (0.0, 0.0, 0.0), (0.0, 0.0, math.pi / 2))


def cup_seen(xyz: tuple[float, float, float] = (0.9, -0.3, 0.79)) -> ObservedObject:
    return ObservedObject("cup", "cup", "cylinder", [0.04, 0.1], list(xyz), [0, 0, 0], 0.9)


def frame(
    seq: int, t_s: float, *objects: ObservedObject, removed: tuple[str, ...] = ()
) -> Perception:
    return Perception(round(t_s * S), seq, "camera", list(objects), list(removed))


def facing_head(gap: float) -> np.ndarray:
    """DH angles [rad] that hold a cup (radius 40 mm, centred on the gripper frame) with its
    surface ``gap`` [m] from the head, approaching it from the front."""
    T = np.eye(4)
    T[:3, :3] = FACING_HEAD
    T[:3, 3] = HEAD + np.array([0.110 + gap + 0.04, 0.0, 0.0])
    return np.asarray(ik_nearest(SCENE.in_base(T), UNFOLDED, DEFAULT_ARM))


def gripper_in_chair(q: np.ndarray) -> np.ndarray:
    return np.asarray(SCENE.mount @ fk(q, DEFAULT_ARM))


def test_attach_and_detach_are_versioned_diffs_every_follower_applies() -> None:
    world = WorldModel()
    follower = WorldFollower()
    for update in world.observe(frame(0, 1.0, cup_seen())):
        assert not follower.on_update(update)  # a free cup: nothing held
    grip = pose_matrix([0.0, 0.01, 0.0], (0.0, 0.0, math.pi / 2))
    updates = world.attach("cup", GRIPPER_FRAME, grip, 2 * S, ["gripper"], ["table"])
    diff = updates[0]
    assert (diff.base_version, diff.version) == (1, 2) and diff.removed == []
    held = diff.objects[0]
    assert (held.link, held.touch_links, held.touch_objects) == (
        GRIPPER_FRAME,
        ["gripper"],
        ["table"],
    )
    assert held.xyz == pytest.approx([0.0, 0.01, 0.0]) and held.ypr == pytest.approx(
        [0, 0, math.pi / 2]
    )
    assert (held.stamp_ns, held.source, held.stale) == (2 * S, ARM, False)
    assert all(follower.on_update(u) for u in updates[:1])
    assert follower.held == (
        CUP._replace(size=(0.04, 0.1), xyz=(0.0, 0.01, 0.0), touch_objects=("table",)),
    )
    # Released where it is: back into the chair frame, nothing to touch.
    put = pose_matrix([0.8, -0.2, 0.79], (0.3, 0.0, 0.0))
    updates = world.detach("cup", put, 5 * S)
    free = updates[0].objects[0]
    assert (free.link, free.touch_links, free.touch_objects, free.stamp_ns) == ("", [], [], 5 * S)
    assert free.xyz == pytest.approx([0.8, -0.2, 0.79]) and free.ypr[0] == pytest.approx(0.3)
    assert follower.on_update(updates[0])
    assert [h.name for h in follower.held] == []
    assert (follower.objects, follower.version) == (world.objects, world.version)
    # A follower that missed the attach learns it from the next whole set.
    late = WorldFollower()
    world.attach("cup", GRIPPER_FRAME, grip, 6 * S, ["gripper"])
    assert not late.on_update(updates[0]) and (late.objects, late.version) == ({}, 0)
    assert late.on_update(world.full()) and [h.name for h in late.held] == ["cup"]


def test_a_held_object_is_not_moved_removed_or_staled_by_perception() -> None:
    world = WorldModel()
    world.observe(frame(0, 1.0, cup_seen()))
    grip = np.eye(4)
    world.attach("cup", GRIPPER_FRAME, grip, round(1.5 * S), ["gripper"])
    held = world.objects["cup"]
    # Frames captured before the grasp (latency) and after it (the camera still sees
    # a cup on the table, or lost it) leave the held cup alone, and it never goes stale.
    for seq, t in enumerate((1.4, 1.6, 2.0)):
        world.observe(frame(seq + 1, t, cup_seen()))
    world.observe(frame(4, 2.1, removed=("cup",)))
    for seq in range(5, 60):
        world.observe(frame(seq, 0.1 * seq))
    assert world.objects["cup"] == held
    assert world.stale_reason("cup", 30 * S) == "" and not world.objects["cup"].stale
    # Released at 6.0 s: a frame captured before that (the cup still in the gripper,
    # lifted) does not move it back; a later one does.
    put = pose_matrix([0.8, -0.2, 0.79], (0.0, 0.0, 0.0))
    world.detach("cup", put, 6 * S)
    world.observe(frame(60, 5.95, cup_seen((0.8, -0.2, 0.95))))
    assert world.objects["cup"].xyz == pytest.approx([0.8, -0.2, 0.79])
    world.observe(frame(61, 6.1, cup_seen((0.81, -0.2, 0.79))))
    assert world.objects["cup"].xyz == pytest.approx([0.81, -0.2, 0.79])
    assert world.objects["cup"].source == "camera"
    # And once released, it goes stale when no frame sees it.
    world.observe(frame(62, 9.0))
    assert "was last observed 2.9 s ago" in world.stale_reason("cup")


def attach(core: PlannerCore, request: AttachRequest) -> tuple[AttachReply, list[WorldUpdate]]:
    """Ask the planner's queryable as its shell would (its wiring map)."""
    out = PLANNER.feed(core, ep.ATTACH.trace("request"), request, 0)
    reply = next(m for k, m in out if k == ep.ATTACH.trace("reply"))
    assert isinstance(reply, AttachReply)
    return reply, [m for k, m in out if k == ep.OBJECTS and isinstance(m, WorldUpdate)]


def test_the_planner_attaches_centred_between_the_jaws_and_carries_the_cup() -> None:
    core = PlannerCore()
    q = facing_head(0.2)
    gripper = gripper_in_chair(q)
    # Perception saw the cup 6 mm off the jaws' axis and 3 mm behind the grasp point.
    seen = gripper @ pose_matrix([0.006, 0.0, -0.003], (0.0, 0.0, math.pi / 2))
    core.world.observe(frame(0, 1.0, cup_seen(tuple(seen[:3, 3]))))
    reply, updates = attach(core, AttachRequest("cup", GRIPPER_FRAME, list(q), 2 * S))
    assert reply.accepted and reply.object is not None and reply.version == 2
    assert updates and updates[0].objects == [reply.object]
    assert reply.object.xyz == pytest.approx([0.0, 0.0, -0.003], abs=1e-9)  # centred in x
    assert reply.object.touch_links == ["gripper"]
    assert core.collision is not None and [h.name for h in core.collision.held] == ["cup"]
    # Attached again with a touch object: held where it is.
    reply, _ = attach(
        core,
        AttachRequest("cup", GRIPPER_FRAME, list(facing_head(0.3)), 3 * S, touch_objects=["table"]),
    )
    assert reply.accepted and reply.object is not None
    assert reply.object.xyz == pytest.approx([0.0, 0.0, -0.003], abs=1e-9)
    assert core.collision.held[0].touch_objects == ("table",)
    # Released at another configuration: where the gripper holds it there.
    q2 = facing_head(0.3)
    reply, _ = attach(core, AttachRequest("cup", "", list(q2), 4 * S))
    assert reply.accepted and reply.object is not None and reply.object.link == ""
    expected = gripper_in_chair(q2) @ pose_matrix([0.0, 0.0, -0.003], (0.0, 0.0, math.pi / 2))
    assert reply.object.xyz == pytest.approx(list(expected[:3, 3]), abs=1e-9)
    assert core.collision.held == ()


@pytest.mark.parametrize(
    ("request_", "message"),
    [
        (AttachRequest("mug", GRIPPER_FRAME, [0.0] * 6, 0), r"no object 'mug' .*\(known: cup\)"),
        (AttachRequest("cup", "link4", [0.0] * 6, 0), "objects attach to 'gripper_frame'"),
        (AttachRequest("cup", GRIPPER_FRAME, [math.nan] * 6, 0), "6 finite angles"),
        (
            AttachRequest("cup", GRIPPER_FRAME, [0.0] * 6, 0, touch_links=["thumb"]),
            "touch link 'thumb' is not an arm body",
        ),
        (
            AttachRequest("cup", GRIPPER_FRAME, [0.0] * 6, 0, touch_objects=["desk"]),
            "touch object 'desk' is not in the scene",
        ),
        (AttachRequest("cup", GRIPPER_FRAME, [0.0] * 6, 0, xyz=[0, 0, 0]), "both xyz and ypr"),
        (AttachRequest("cup", "", [0.0] * 6, 0), "'cup' is not attached to the arm"),
        (AttachRequest("cup", GRIPPER_FRAME, [0.0] * 6, 0), r"is \d+ mm from the grasp point"),
    ],
)
def test_a_bad_attach_is_refused_naming_the_object_and_the_reason(
    request_: AttachRequest, message: str
) -> None:
    core = PlannerCore()
    core.world.observe(frame(0, 1.0, cup_seen()))
    before = (dict(core.world.objects), core.world.version, core.collision)
    reply, updates = attach(core, request_)
    assert not reply.accepted and reply.object is None and updates == []
    assert reply.version == 1
    assert reply.error.startswith("no object" if "mug" in message else "object 'cup'")
    assert re.search(message, reply.error), reply.error
    assert (core.world.objects, core.world.version, core.collision) == before


def test_a_held_cup_inside_the_persons_clearance_is_refused_where_the_arm_alone_is_clear() -> None:
    arm_only = CollisionModel(SCENE, DEFAULT_ARM, opening=0.08)
    holding = arm_only.holding([CUP])
    q = facing_head(0.03)  # the cup 30 mm from the head, the fingertips 60 mm
    bare, held = arm_only.clearance(q), holding.clearance(q)
    assert bare.margin >= 0.0 and bare.check.other == "head" and bare.check.body == "gripper"
    assert held.margin < 0.0 and (held.check.body, held.check.other) == ("cup", "head")
    assert held.distance == pytest.approx(0.03, abs=1e-4)
    assert held.describe() == "cup 30.0 mm from head (person: needs 50 mm)"
    assert checker_for(arm_only).is_valid(q) and not checker_for(holding).is_valid(q)
    # The guard's probe and the fast check name the cup too.
    assert holding.probe(q).best.check.body == "cup"
    assert checker_for(holding).margins(q).check.body == "cup"


def test_the_planner_refuses_a_move_that_brings_the_held_cup_to_the_head() -> None:
    core = PlannerCore()
    start = facing_head(0.07)
    seen = gripper_in_chair(start) @ CUP.placement()
    core.world.observe(frame(0, 1.0, cup_seen(tuple(seen[:3, 3]))))
    # 40 mm toward the head: the fingertips stay 60 mm away, the cup comes to 30 mm.
    path = parse_viapoints(
        "0 0 0 0 0 0 0 0 0 0 0 0 0 2\n-40 0 0 0 0 0 0 0 0 0 0 0 3 2\n", "toward.txt"
    )
    request = PlanRequest(ViaPointPath(path=path), start=list(start), preview_dt=0.0)
    assert core.plan(request).ok  # nothing held yet: the arm alone is clear
    reply, _ = attach(core, AttachRequest("cup", GRIPPER_FRAME, list(start), 2 * S))
    assert reply.accepted
    refused = core.plan(request)
    assert not refused.ok and refused.error is not None and refused.error.reason == "collision"
    assert (
        "cup" in refused.error.message
        and "from head (person: needs 50 mm)" in refused.error.message
    )


def test_a_scene_update_keeps_what_the_arm_holds_in_every_model() -> None:
    from manus.scene import default_scene_path
    from schemas.collision import SceneUpdate
    from services.controller.core import ControllerCore
    from services.controller.wiring import WIRING as CONTROLLER
    from services.sequencer.core import SequencerCore
    from services.sequencer.wiring import WIRING as SEQUENCER

    core = PlannerCore()
    start = facing_head(0.2)
    seen = gripper_in_chair(start) @ CUP.placement()
    core.world.observe(frame(0, 1.0, cup_seen(tuple(seen[:3, 3]))))
    _, updates = attach(core, AttachRequest("cup", GRIPPER_FRAME, list(start), 2 * S))
    controller, sequencer = ControllerCore(), SequencerCore()
    for update in updates:
        CONTROLLER.feed(controller, ep.OBJECTS, update, 0)
        SEQUENCER.feed(sequencer, ep.OBJECTS, update, 0)
    moved = default_scene_path().read_text().replace("[1100, 0, 720]", "[1000, 100, 700]")
    published = PLANNER.feed(core, ep.SCENE.trace("request"), SceneUpdate(moved), 0)
    state = next(m for k, m in published if k == ep.SCENE_STATE)
    CONTROLLER.feed(controller, ep.SCENE_STATE, state, 0)
    SEQUENCER.feed(sequencer, ep.SCENE_STATE, state, 0)
    assert core.collision is not None and core.collision.scene is not None
    assert controller.guard is not None and sequencer.fold_check is not None
    for model in (core.collision, controller.guard.guard.model, sequencer.fold_check.model):
        assert model.scene is not None and model.scene.version == 1
        assert [h.name for h in model.held] == ["cup"]
