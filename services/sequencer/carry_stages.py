"""The stages of ``place`` and ``give`` (an object the arm holds: carried level, put down
or handed over), and the tilt check of every motion planned while a level object is
held (docs/pick.md). Pure functions, as :mod:`services.sequencer.object_stages`.
"""

from __future__ import annotations

import math

import numpy as np

from manus.grasp_poses import extent_along, object_pose, tilt
from manus.kinematics import fk_batch
from manus.orientation import pose_matrix, rot_z
from manus.trajectory import JointTrajectory
from manus.urdf import GRIPPER_FRAME
from schemas.objects import ObjectShape, WorldObject
from schemas.planning import Trajectory
from services.sequencer.object_stages import (
    MAX_OPENING_M,
    NEAR_SPEED,
    ObjectProblem,
    ObjectView,
    Stage,
    half_height,
    line_to,
    line_up,
    surface_top,
    surface_under,
)

UPRIGHT_DEG = 2.0
"""A place pose leaning more than this from upright is refused [deg]: objects rest upright."""

LOWER_TOLERANCE_M = 0.004
"""Lowering may end this far short of its end [m] (the controller slowing by the
surface): the object drops ``pick.drop_m`` anyway."""

TILT_SAMPLE_S = 0.02
"""Time between two samples of a trajectory's tilt check [s]."""

SYMMETRIC = (ObjectShape.CYLINDER, ObjectShape.SPHERE, ObjectShape.CAPSULE)
"""Shapes whose yaw does not matter: they are put down with the gripper's yaw kept."""


def held_object(view: ObjectView, object_id: str) -> WorldObject:
    """The object ``object_id`` as the arm holds it.

    Raises:
        ObjectProblem: unknown, or not held.
    """
    obj = view.find(object_id)
    if obj.link != GRIPPER_FRAME:
        raise ObjectProblem(
            f"object {object_id!r} is not held by the gripper (pick it first: a pick step)"
        )
    return obj


def _world_pose(view: ObjectView, held: WorldObject, q: np.ndarray) -> np.ndarray:
    return np.asarray(view.gripper(q) @ object_pose(held))


PLACE_TURNS_DEG = (0.0, 15.0, -15.0, 30.0, -30.0, 45.0, -45.0)
"""The gripper's candidate yaws at a place, from pointing away from the shoulder [deg]
(a symmetric object: its own yaw does not matter)."""


def place_stages(
    view: ObjectView,
    held: WorldObject,
    q: np.ndarray,
    at: list[float] | None,
    surface: str,
    turn_deg: float = 0.0,
) -> list[Stage]:
    """Carry the held object above its place (a straight line, else a search), lower it,
    let it go there, retreat straight up (the open jaws rise off it).

    Args:
        view: what the sequencer knows.
        held: the object, attached (its pose in the gripper frame).
        q: the arm's configuration when the place begins [rad].
        at: the object's centre pose, chair frame (x, y, z [m], yaw, pitch, roll [rad]);
            None: on ``surface``, under where it is held.
        surface: the scene object to put it on (with ``at`` None).
        turn_deg: a symmetric object: the gripper's yaw from pointing away from the
            shoulder [deg] (:data:`PLACE_TURNS_DEG`).

    Raises:
        ObjectProblem: the place pose leans, is inside or far above a surface, or the
            surface is unknown or not under the object.
    """
    now = _world_pose(view, held, q)
    hh = half_height(held_as_world(held, now))
    if at is not None:
        target = pose_matrix(np.array(at[:3]), (at[3], at[4], at[5]))
        lean = math.degrees(tilt(target[:3, :3]))
        if lean > UPRIGHT_DEG:
            raise ObjectProblem(
                f"object {held.id!r} cannot be placed leaning {lean:.1f} deg: objects rest "
                f"upright (at most {UPRIGHT_DEG:g} deg)"
            )
        bottom = target[2, 3] - hh
        on = surface_under(view.scene, held_as_world(held, target), bottom)
        if not on:
            raise ObjectProblem(
                f"object {held.id!r}: nothing to put it on at ({target[0, 3] * 1e3:.0f}, "
                f"{target[1, 3] * 1e3:.0f}, {target[2, 3] * 1e3:.0f}) mm: its bottom must be "
                "on the top of a scene object (within 15 mm)"
            )
    else:
        on = surface
        target = _on_surface(view, held, now, surface, hh)
    T_g = target @ np.linalg.inv(object_pose(held))
    if held.shape in SYMMETRIC:
        # Its yaw does not matter: the gripper turns (about the vertical, so the object
        # stays as level as it is) to point away from the shoulder, as a grasp there would.
        seen = target[:2, 3] - view.mount[:2, 3]
        z = T_g[:3, 2]
        turn = math.atan2(seen[1], seen[0]) - math.atan2(z[1], z[0]) + math.radians(turn_deg)
        centre = target[:3, 3].copy()
        T_g = _turned(T_g, turn, centre)
    T_g[2, 3] += view.config.drop_m
    above = T_g.copy()
    above[2, 3] += view.how(held).lift
    width = extent_along(held, np.array([1.0, 0.0, 0.0]))
    return [
        Stage("carry", motion=line_to(view, above), carrying=True, retry=True),
        Stage("set down", attach=GRIPPER_FRAME, touch_objects=(on,)),
        Stage(
            "lower",
            motion=line_to(view, T_g, speed=NEAR_SPEED),
            carrying=True,
            retry=True,
            reach_tolerance=LOWER_TOLERANCE_M,
            onto=on,
            raised=line_to(view, _raised(view, T_g), speed=NEAR_SPEED),
        ),
        Stage("open", opening=min(MAX_OPENING_M, width + view.how(held).open_margin)),
        Stage("release", attach=""),
        Stage("retreat", motion=line_up(view, 2.0 * hh + 0.02)),
    ]


GIVE_TURNS_DEG = (0.0, 30.0, -30.0, 60.0, -60.0)
"""The gripper's candidate yaws at the hand-over, from ``pick.handover_yaw_deg`` [deg]."""


def give_stages(
    view: ObjectView,
    held: WorldObject,
    q: np.ndarray,
    turn_deg: float = 0.0,
    at: list[float] | None = None,
) -> list[Stage]:
    """Carry the held object to the hand-over pose near the user (the gripper's yaw
    ``pick.handover_yaw_deg`` plus ``turn_deg``, turned about the vertical from where it
    is, so a level object stays level) and hold it there.

    Args:
        at: the task's own hand-over pose instead of the sequencer's: the object's centre,
            chair frame (x, y, z [m]), and the gripper's yaw (its pitch and roll: 0) [rad].

    Raises:
        ObjectProblem: ``at`` asks for a pitch or a roll.
    """
    centre, yaw_deg = view.config.handover_xyz, view.config.handover_yaw_deg
    if at is not None:
        if abs(at[4]) > 1e-9 or abs(at[5]) > 1e-9:
            raise ObjectProblem(
                f"object {held.id!r}: a hand-over turns the gripper about the vertical only "
                f"(its yaw), got pitch {math.degrees(at[4]):.1f} deg and roll "
                f"{math.degrees(at[5]):.1f} deg (write 0 0)"
            )
        centre, yaw_deg = (at[0], at[1], at[2]), math.degrees(at[3])
    T_now = view.gripper(q)
    z = T_now[:3, 2] if abs(T_now[2, 2]) < 0.9 else T_now[:3, 0]
    yaw = math.radians(yaw_deg + turn_deg)
    turn = yaw - math.atan2(z[1], z[0])
    R = rot_z(turn) @ T_now[:3, :3]
    T_g = np.eye(4)
    T_g[:3, :3] = R
    T_g[:3, 3] = np.array(centre) - R @ np.array(held.xyz)
    return [Stage("hand over", motion=line_to(view, T_g), carrying=True, retry=True)]


def plan_problem(
    view: ObjectView,
    stage: Stage,
    trajectory: Trajectory,
    held: WorldObject | None,
    margin: float | None = None,
) -> str:
    """What keeps a stage's planned ``trajectory`` from being run ('' nothing): a
    clearance within ``margin`` (default ``pick.margin_m``) of its limit on the way (the
    controller's tracking error would bring the guard's stop; at the start it is where
    the arm is, which the motion cannot change), or, carrying a level object, too much
    tilt."""
    report = trajectory.clearance
    margin = view.config.margin_m if margin is None else margin
    onto = (
        held is not None
        and report is not None
        and (report.body, report.other)
        == (
            held.id,
            stage.onto,
        )
    )
    tight = report is not None and report.distance - report.required < margin
    if report is not None and report.time > 0.0 and tight and not onto:
        return (
            f"{stage.label}: too tight: {report.body} {report.distance * 1e3:.1f} mm from "
            f"{report.other} at {report.time:.2f} s ({report.cls}: needs "
            f"{report.required * 1e3:.0f} mm, and {margin * 1e3:.0f} mm to spare for tracking)"
        )
    if stage.carrying and held is not None:
        return tilt_problem(view, held, trajectory, stage.label)
    return ""


def held_as_world(held: WorldObject, pose: np.ndarray) -> WorldObject:
    """``held`` at the chair-frame pose ``pose`` (for its extents and surfaces)."""
    from dataclasses import replace

    from manus.orientation import matrix_to_ypr

    ypr = [float(v) for v in matrix_to_ypr(pose[:3, :3])]
    return replace(held, xyz=[float(v) for v in pose[:3, 3]], ypr=ypr, link="")


def _raised(view: ObjectView, T: np.ndarray) -> np.ndarray:
    """``T`` raised so that the held object ends 1 mm outside the environment's clearance
    above the surface it is let go over (``pick.drop_m`` above it at ``T``)."""
    clearance = view.scene.clearance.get("environment", 0.015) if view.scene else 0.0
    up = T.copy()
    up[2, 3] += max(0.0, clearance + 0.001 - view.config.drop_m)
    return up


def _turned(T: np.ndarray, turn: float, centre: np.ndarray) -> np.ndarray:
    """The pose ``T`` turned by ``turn`` [rad] about the vertical through ``centre``."""
    R = np.eye(4)
    R[:3, :3] = rot_z(turn)
    R[:3, 3] = centre - R[:3, :3] @ centre
    return np.asarray(R @ T)


def _on_surface(
    view: ObjectView, held: WorldObject, now: np.ndarray, surface: str, hh: float
) -> np.ndarray:
    scene = view.scene
    found = next((s for s in scene.objects if s.name == surface), None) if scene else None
    if found is None:
        known = ", ".join(s.name for s in scene.objects) if scene is not None else "no scene"
        raise ObjectProblem(f"object {held.id!r}: no surface {surface!r} (known: {known})")
    x, y = now[0, 3], now[1, 3]
    top = surface_top(found.body.shape, found.body.size, found.body.pose, x, y)
    if top is None:
        raise ObjectProblem(
            f"object {held.id!r} is not above surface {surface!r} (held at "
            f"({x * 1e3:.0f}, {y * 1e3:.0f}) mm; only upright boxes and cylinders have tops)"
        )
    target = np.eye(4)
    target[:3, 3] = (x, y, top + hh)
    return target


def max_tilt(view: ObjectView, trajectory: Trajectory, up: np.ndarray) -> tuple[float, float]:
    """The largest tilt [rad] of a held object whose upright axis is ``up`` (gripper
    frame) along ``trajectory``, and when [s]: every knot and every
    :data:`TILT_SAMPLE_S`."""
    jt = JointTrajectory(trajectory)
    times = np.union1d(np.asarray(trajectory.times), np.arange(0.0, jt.duration, TILT_SAMPLE_S))
    q = np.array([jt.sample(float(t)).q for t in times])
    R = view.mount[:3, :3] @ fk_batch(q, view.arm)[:, :3, :3]
    axis = R @ up
    angles = np.arccos(np.clip(axis[:, 2], -1.0, 1.0))
    i = int(np.argmax(angles))
    return float(angles[i]), float(times[i])


def tilt_problem(view: ObjectView, held: WorldObject, trajectory: Trajectory, label: str) -> str:
    """Why ``trajectory`` (a stage ``label`` carrying ``held``, attached: its pose in the
    gripper frame) tilts it too far ('' when it keeps it level, or its class need not be)."""
    how = view.grasps.get(held.cls)
    if how is None or not how.keep_level or not held.link:
        return ""
    worst, when = max_tilt(view, trajectory, object_pose(held)[:3, 2])
    held_cls = held.cls
    limit = view.config.max_tilt_deg
    if math.degrees(worst) <= limit:
        return ""
    return (
        f"{label}: the {held_cls} would tilt {math.degrees(worst):.1f} deg at {when:.2f} s "
        f"(it is kept within {limit:g} deg: it may hold a drink)"
    )
