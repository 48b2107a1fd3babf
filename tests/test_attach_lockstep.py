"""Attached objects in lock-step, judged on the simulator's truth: the gripper closes on
the cup, the planner attaches it (``planner/attach``), the controller's guard and the
sequencer's fold check follow ``planner/objects``; a jog toward the user's head stops
when the held cup (not the arm) reaches the person's clearance; a fold with the cup
held is refused where it would bring it into the arm's base; the controller's run
replays byte for byte."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from manus.collision import CollisionModel
from manus.config import DEFAULT_ARM, UNFOLDED_Q_DEG
from manus.kinematics import fk, ik_nearest
from manus.scene import default_scene, pose_matrix
from manus.urdf import GRIPPER_FRAME
from manus_stack.jog_lockstep import JogArm
from manus_stack.regression import check_controller, check_planner
from manus_stack.task_lockstep import TaskLockStep
from schemas import endpoints as ep
from schemas.control import GoalAck, GripperGoal, TrajectoryGoal
from schemas.jog import JogLevel, LimitKind
from schemas.objects import AttachReply, AttachRequest, WorldUpdate
from schemas.planning import Trajectory
from schemas.sequencing import StepKind, Task, TaskStep
from services.controller.core import ControllerCore
from services.controller.wiring import WIRING as CONTROLLER
from services.planner.core import PlannerCore
from services.planner.wiring import WIRING as PLANNER
from services.recorder.writer import RecordingWriter
from services.simulator.camera_config import CameraConfig
from services.simulator.config import SimConfig
from services.simulator.objects import SimObject
from tests.object_rig import CUP_LENGTH, CUP_RADIUS, cup_centre, grasp_q_deg

SCENE = default_scene()
PERSON_M = SCENE.clearance["person"]
HEAD = next(o for o in SCENE.objects if o.name == "head")
STILL_CAMERA = CameraConfig(noise_mm=0.0, noise_deg=0.0, dropout=0.0, frame_dropout=0.0)
"""The simulated camera without noise or dropouts: the held cup where it truly is."""


def ask_planner(arm: JogArm, request: AttachRequest) -> AttachReply:
    """Ask ``planner/attach`` as the live node mirrors it (recorded, replayable)."""
    before = len(arm.ls.messages)
    arm.ls.publish(ep.ATTACH.trace("request"), request)
    arm.ls.run_for(0.01)
    return next(
        m
        for _, s, m in arm.ls.messages[before:]
        if s == ep.ATTACH.trace("reply") and isinstance(m, AttachReply)
    )


def toward_the_head() -> np.ndarray:
    """DH angles [rad]: the gripper 400 mm in front of the user's face and to the right,
    level, approaching it (its jaw axis level)."""
    direction = np.array([0.878, -0.3, 0.0]) / np.linalg.norm([0.878, -0.3])
    T = np.eye(4)
    z = -direction
    x = np.array([-z[1], z[0], 0.0])
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = HEAD.body.pose[:3, 3] + np.array([0.0, 0.0, -0.03]) + 0.4 * direction
    return np.asarray(ik_nearest(SCENE.in_base(T), np.radians(UNFOLDED_Q_DEG), DEFAULT_ARM))


def joint_move(q0: np.ndarray, q1: np.ndarray, duration: float) -> Trajectory:
    """A smooth joint-space move (at rest at both ends), 9 knots."""
    d = q1 - q0
    s = np.linspace(0.0, 1.0, 9)
    return Trajectory(
        times=[float(x * duration) for x in s],
        positions=[[float(v) for v in q0 + d * (3 * x**2 - 2 * x**3)] for x in s],
        velocities=[[float(v) for v in d * (6 * x - 6 * x**2) / duration] for x in s],
    )


def cup_before_the_face(attach: bool) -> JogArm:
    """The arm at the cup on the table, jaws open; the camera reports the cup to the
    planner; the gripper closes on it (the simulator holds it) and, if ``attach``, the
    planner attaches it (the table it stands on a touch object); then a joint move
    carries it up in front of the user's face, the gripper approaching it."""
    sim = SimConfig().with_overrides(
        start_pose=grasp_q_deg(), start_gripper_mm=90.0, objects="none", camera=STILL_CAMERA
    )
    arm = JogArm(sim)
    cup = SimObject(
        "cup",
        "cup",
        "cylinder",
        (CUP_RADIUS, CUP_LENGTH),
        pose_matrix(list(cup_centre()), (0, 0, 0)),
    )
    arm.ls.sim.objects.add(cup)
    arm.ls.attach(PLANNER, PlannerCore())
    arm.start()
    arm.run(0.5)
    close = GripperGoal("close", opening=2 * CUP_RADIUS - 0.002, tolerance=0.004)
    assert arm.query(ep.GRIPPER_GOAL, close).accepted
    arm.run(2.0)
    truth = {o.id: o for o in arm.ls.sim.truth().objects}
    assert truth["cup"].held, "the simulator's gripper did not take the cup"
    grasped = arm.core.last_js
    assert grasped is not None
    if attach:
        request = AttachRequest(
            "cup", GRIPPER_FRAME, list(grasped.position), grasped.stamp_ns, touch_objects=["table"]
        )
        reply = ask_planner(arm, request)
        assert reply.accepted, reply.error
    assert arm.query(ep.JOG_LEVEL, JogLevel(level=3)).accepted
    arm.stream(1.5, units="unitless", linear=[0.0, 0.0, 1.0])  # lift it off the table
    arm.send()  # and release the controls (a zero command)
    arm.run(0.5)
    lifted = arm.core.last_js
    assert lifted is not None
    move = joint_move(np.asarray(lifted.position), toward_the_head(), 12.0)
    assert arm.submit(TrajectoryGoal("up", move)).accepted
    result = arm.run_until_result("up", timeout_s=20.0)
    assert result.status == "succeeded", result
    return arm


def jog_toward_the_head(arm: JogArm) -> None:
    """Jog the gripper straight at the head's centre, at the fastest level, for 8 s."""
    assert arm.query(ep.JOG_LEVEL, JogLevel(level=5)).accepted
    head = (np.linalg.inv(SCENE.mount) @ HEAD.body.pose)[:3, 3]
    gripper = fk(arm.samples[-1].q, DEFAULT_ARM)[:3, 3]
    toward = (head - gripper) / np.linalg.norm(head - gripper)
    arm.stream(8.0, units="unitless", linear=list(toward))


def test_a_jog_stops_when_the_held_cup_reaches_the_persons_clearance_on_the_truth(
    tmp_path: Path,
) -> None:
    arm = cup_before_the_face(attach=True)
    guard = arm.core.guard
    assert guard is not None and [h.name for h in guard.guard.model.held] == ["cup"]
    jog_toward_the_head(arm)
    truth = arm.ls.sim.truth()
    # The truth: the held cup never came within the person's clearance, nothing touched
    # the person, and the cup did come close (the guard stopped it there).
    assert truth.held_min_person is not None
    assert PERSON_M - 0.002 <= truth.held_min_person < PERSON_M + 0.03, truth.held_min_person
    assert truth.contacts == 0
    assert not [c for c in truth.object_contacts if c.cls == "person"]
    arm_alone = CollisionModel(SCENE, DEFAULT_ARM, opening=truth.gripper)
    margins = arm_alone.margins(arm.samples[-1].q)
    arm_to_head = min(
        m + c.required for m, c in zip(margins, arm_alone.checks, strict=True) if c.other == "head"
    )
    assert arm_to_head > truth.held_min_person + 0.02  # the arm itself stayed further
    assert all(s.at_rest for s in arm.samples[-20:])
    last = arm.states()[-1]
    # Typed fields (schemas.jog.JogLimit): the guard holds the jog at the cup, near the head.
    held = [lim for lim in last.limits if lim.kind == LimitKind.COLLISION]
    assert last.active and held, last
    assert held[0].object == "head" and held[0].body == "cup" and held[0].scale == 0.0, held
    assert PERSON_M - 0.002 <= held[0].distance < PERSON_M + 0.03, held
    assert last.reason == "stopped by the collision guard: cup near head (person: keeps 50 mm)"

    # The run replays byte for byte: the controller's inputs include the world model's
    # updates (its wiring map), the planner's the attach request.
    path = tmp_path / "held.mcap"
    with RecordingWriter(path) as writer:
        for t_ns, suffix, msg in arm.ls.messages:
            writer.write(suffix, msg, t_ns)
    for result in (check_controller(path), check_planner(path)):
        assert result.ok and result.compared > 50, result.difference


def test_without_the_attach_the_guard_lets_the_cup_into_the_clearance() -> None:
    """The same jog, the cup held by the simulator but not attached: the guard keeps
    only the arm's bodies clear, and the truth shows the cup inside the clearance (what
    the attach is for)."""
    arm = cup_before_the_face(attach=False)
    jog_toward_the_head(arm)
    truth = arm.ls.sim.truth()
    assert truth.held_min_person is not None and truth.held_min_person < PERSON_M - 0.01


def test_the_fold_check_refuses_folding_in_with_the_held_cup_into_the_shoulder() -> None:
    run = TaskLockStep(SimConfig(start_pose="unfolded", objects="default"))
    run.start_arm()
    run.ls.run_for(0.5)  # the camera's frames: the planner knows the cup
    fold_in = Task(steps=[TaskStep(kind=StepKind.FOLD_IN)], name="fold")
    js = run.controller.last_js
    assert js is not None and "cup" in run.planner.world.objects
    # Held across the jaws, as the sequencer's grasp step will attach it.
    held = AttachRequest(
        "cup", GRIPPER_FRAME, list(js.position), js.stamp_ns, xyz=[0, 0, 0], ypr=[0, 0, math.pi / 2]
    )
    reply = run.answer(held)
    assert isinstance(reply, AttachReply) and reply.accepted
    run.ls.run_for(0.01)
    assert run.seq.fold_check is not None
    assert [h.name for h in run.seq.fold_check.model.held] == ["cup"]
    guard = run.controller.guard
    assert guard is not None and [h.name for h in guard.guard.model.held] == ["cup"]
    refused = run.submit(fold_in, "with-cup")
    assert not refused.accepted and len(refused.errors) == 1, refused.errors
    assert (
        "step 1 (fold_in): fold in from (0, 30, -30, 0, -60, 0) deg would bring the cup "
        in (refused.errors[0])
    )
    assert "from shoulder (self: needs 10 mm)" in refused.errors[0]
    # Released: the arm alone folds clear of its base.
    js = run.controller.last_js
    assert js is not None
    released = run.answer(AttachRequest("cup", "", list(js.position), js.stamp_ns))
    assert isinstance(released, AttachReply) and released.accepted
    run.ls.run_for(0.01)
    assert run.seq.fold_check.model.held == ()
    assert run.submit(fold_in, "without").accepted


def test_a_controller_started_late_learns_the_held_cup_from_the_whole_set() -> None:
    arm = cup_before_the_face(attach=True)
    late = ControllerCore()
    updates = [u for u in arm.ls.published(ep.OBJECTS) if isinstance(u, WorldUpdate)]
    diffs = [u for u in updates if u.base_version != -1]
    for update in diffs[-1:]:  # a diff from a version it does not hold: waits
        CONTROLLER.feed(late, ep.OBJECTS, update, 0)
    assert late.guard is not None and not late.guard.guard.model.held
    arm.run(1.1)  # the next whole set (every second)
    whole = [
        u
        for u in arm.ls.published(ep.OBJECTS)
        if isinstance(u, WorldUpdate) and u.base_version == -1
    ]
    CONTROLLER.feed(late, ep.OBJECTS, whole[-1], 0)
    assert [h.name for h in late.guard.guard.model.held] == ["cup"]
    assert isinstance(arm.query(ep.JOG_LEVEL, JogLevel(level=1)), GoalAck)
