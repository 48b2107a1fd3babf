"""``manus plan --to-pose X Y Z YAW PITCH ROLL``, ``--to-joints Q1..Q6``, ``--to NAME``,
``--to-object NAME X Y Z YAW PITCH ROLL``, ``--approach MM``: plan a goal in-process and
print the trajectory as JSON, as ``manus plan FILE`` does (:mod:`.plan_cli`).

Thesis units at this edge: millimetres and degrees; a pose is ``X Y Z YAW PITCH ROLL``
(R = Rz(yaw) Ry(pitch) Rx(roll)), the order ``manus kin fk`` prints. A goal that cannot
be reached exits 1 with the reason on one line of standard error; nothing moves (use
``manus reach`` / ``manus move-to`` to run it on the stack).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

import numpy as np

from manus.config import load_arm_config
from manus.named_poses import NamedPoseError
from manus_stack.pose_args import POSE_HELP, POSE_ORDER, add_pose_argument, pose_values
from schemas.goals import (
    JointGoal,
    LineFrame,
    LineMotion,
    NamedGoal,
    ObjectGoal,
    PoseGoal,
    Search,
    Tolerance,
)
from schemas.motion import Motion
from schemas.planning import PlanRequest, Trajectory
from services.planner import plan_cli
from services.planner.config import PlannerConfig
from services.planner.core import PlannerCore
from services.planner.errors import PlanningError, refuse

GOAL_OPTIONS = ("to_pose", "to_joints", "to", "to_object", "approach")
"""The goal options (at most one)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``manus plan FILE``'s arguments, the goal options and the search's settings."""
    plan_cli.add_arguments(parser)
    add_goal_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Plan the goal the options name, else ``args.file``; print JSON."""
    goal = goal_from_args(args)
    if goal is None:
        if args.file is None:
            raise refuse("invalid", "give a via-point file or a goal (--to-pose, --to, ...)")
        return plan_cli.run(args)
    if args.file is not None:
        raise refuse("invalid", f"give a via-point file or a goal, not both ({args.file})")
    return run_goal(args, goal)


def add_goal_arguments(parser: argparse.ArgumentParser) -> None:
    """The goal options (one of them) and the search's settings."""
    add_pose_argument(parser, "--to-pose", help_text=f"goal: {POSE_HELP}")
    group = parser
    group.add_argument(
        "--to-joints", nargs=6, type=float, metavar="Q", help="goal: DH joint angles [deg]"
    )
    group.add_argument(
        "--to", metavar="NAME", help="goal: a named pose (home, drink, folded, unfolded, ...)"
    )
    group.add_argument(
        "--to-object",
        nargs=7,
        metavar=("NAME", *POSE_ORDER),
        help="goal: a gripper pose in a scene object's frame [mm, deg]",
    )
    group.add_argument(
        "--approach",
        type=float,
        metavar="MM",
        help="a straight line along the gripper's axis [mm] (negative: retreat)",
    )
    parser.add_argument(
        "--free-axis",
        action="store_true",
        help="any turn about the gripper's axis is fine (pose and object goals)",
    )
    parser.add_argument(
        "--tolerance-mm", type=float, default=0.0, help="position tolerance of the goal [mm]"
    )
    parser.add_argument(
        "--tolerance-deg", type=float, default=0.0, help="orientation tolerance of the goal [deg]"
    )
    parser.add_argument("--seed", type=int, default=1, help="seed of the search (default 1)")
    parser.add_argument(
        "--budget", type=int, default=3000, help="most search iterations (default 3000)"
    )
    parser.add_argument(
        "--speed",
        type=float,
        default=0.5,
        help="fraction of the joint speed and acceleration limits to use (default 0.5)",
    )
    parser.add_argument("--poses", default="", help="named poses file (default: $MANUS_POSES)")


def goal_from_args(args: argparse.Namespace) -> Motion | None:
    """The goal motion the options ask for (None: no goal option given).

    Raises:
        PlanningError: ``invalid``: more than one goal, or a number out of range.
    """
    given = [
        f"--{name.replace('_', '-')}" for name in GOAL_OPTIONS if getattr(args, name) is not None
    ]
    if len(given) > 1:
        raise refuse("invalid", f"give one goal, got {', '.join(given)}")
    try:
        search = Search(
            seed=args.seed,
            budget=args.budget,
            speed=args.speed,
            interpolation="quintic" if args.quintic else "cubic",
        )
        tolerance = Tolerance(
            position=args.tolerance_mm * 1e-3,
            angle=math.radians(args.tolerance_deg),
            free_axis=args.free_axis,
        )
        pose = pose_values(args, "--to-pose")
        if pose is not None:
            xyz, ypr = _pose(pose)
            return PoseGoal(xyz=xyz, ypr=ypr, tolerance=tolerance, search=search)
        if args.to_joints is not None:
            return JointGoal(joints=[math.radians(v) for v in args.to_joints], search=search)
        if args.to is not None:
            return NamedGoal(name=args.to, search=search)
        if args.to_object is not None:
            name, *numbers = args.to_object
            xyz, ypr = _pose([_number(v) for v in numbers])
            return ObjectGoal(name=name, xyz=xyz, ypr=ypr, tolerance=tolerance, search=search)
        if args.approach is not None:
            return LineMotion(
                xyz=[0.0, 0.0, args.approach * 1e-3], frame=LineFrame.TOOL, speed=args.speed
            )
    except ValueError as exc:  # a SchemaError: a field out of its range
        raise refuse("invalid", str(exc)) from exc
    return None


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise refuse("invalid", f"--to-object: {text!r} is not a number") from None


def _pose(values: list[float]) -> tuple[list[float], list[float]]:
    return [v * 1e-3 for v in values[:3]], [math.radians(v) for v in values[3:]]


def run_goal(args: argparse.Namespace, motion: Motion) -> int:
    """Plan ``motion`` from ``args.start_joints``; print the trajectory as JSON."""
    config = PlannerConfig(arm=load_arm_config(args.arm_config), scene=args.scene, poses=args.poses)
    try:
        core = PlannerCore(config)
    except NamedPoseError as exc:
        raise refuse("invalid", str(exc)) from exc
    request = PlanRequest(
        motion,
        start=[math.radians(v) for v in args.start_joints],
        preview_dt=0.06 if args.preview else 0.0,
    )
    reply = core.plan(request)
    if reply.error is not None:
        raise PlanningError(reply.error)
    trajectory = reply.trajectory
    assert trajectory is not None
    interpolation = "quintic" if trajectory.accelerations else "cubic"
    out = trajectory_json(trajectory, np.asarray(request.start), interpolation, args.preview)
    out["goal"] = motion.to_dict()
    sys.stdout.write(json.dumps(out) + "\n")
    if trajectory.clearance is not None:
        c = trajectory.clearance
        sys.stderr.write(
            f"smallest clearance: {c.body} {c.distance * 1e3:.1f} mm from {c.other} "
            f"({c.cls}: needs {c.required * 1e3:.0f} mm) at t = {c.time:.2f} s\n"
        )
    return 0


def trajectory_json(
    traj: Trajectory, start: np.ndarray, interpolation: str, preview: bool
) -> dict[str, Any]:
    """What ``manus plan`` prints of a trajectory (degrees, millimetres, seconds)."""
    out: dict[str, Any] = {
        "source": traj.notes[0] if traj.notes else "",
        "interpolation": interpolation,
        "start_deg": _deg(start),
        "times_s": [round(t, 9) for t in traj.times],
        "positions_deg": _deg(traj.positions),
        "velocities_deg_s": _deg(traj.velocities),
        "via_xyz_mm": _mm(traj.via_xyz),
        "via_lines": traj.via_lines,
        "time_scale": traj.time_scale,
        "notes": traj.notes,
        "clearance": None,
        "scene_version": traj.scene_version,
    }
    c = traj.clearance
    if c is not None:
        out["clearance"] = {
            "distance_mm": round(c.distance * 1e3, 3),
            "required_mm": round(c.required * 1e3, 3),
            "body": c.body,
            "other": c.other,
            "class": c.cls,
            "time_s": round(c.time, 6),
        }
    if traj.accelerations:
        out["accelerations_deg_s2"] = _deg(traj.accelerations)
    if preview:
        out["preview_dt_s"] = traj.preview_dt
        out["preview_xyz_mm"] = _mm(traj.preview_xyz)
    return out


def _deg(a: Any) -> list[Any]:
    out: list[Any] = (np.round(np.degrees(np.asarray(a, dtype=float)), 9) + 0.0).tolist()
    return out


def _mm(a: Any) -> list[Any]:
    out: list[Any] = (np.round(np.asarray(a, dtype=float) * 1000.0, 6) + 0.0).tolist()
    return out
