"""``manus plan``: a via-point file (:mod:`services.planner.plan_cli`) or a goal
(:mod:`manus_stack.goal_args`: ``--to-pose X Y Z YAW PITCH ROLL``, ``--to-joints``,
``--to NAME``, ``--to-object``, ``--approach MM``), planned in-process by the planner
core, the trajectory printed as JSON.

Thesis units at this edge: millimetres and degrees. A goal that cannot be reached exits
1 with the reason on one line of standard error; nothing moves (``manus reach`` and
``manus move-to`` run a goal on the stack).
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
from manus_stack.goal_args import add_goal_arguments, goal_from_args
from schemas.motion import Motion
from schemas.planning import PlanRequest, Trajectory
from services.planner import plan_cli
from services.planner.config import PlannerConfig
from services.planner.core import PlannerCore
from services.planner.errors import PlanningError, refuse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``manus plan FILE``'s arguments, the goal options and the search's settings."""
    plan_cli.add_arguments(parser)
    add_goal_arguments(parser)
    parser.add_argument("--poses", default="", help="named poses file (default: $MANUS_POSES)")


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
