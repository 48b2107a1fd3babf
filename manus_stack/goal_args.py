"""The goal options of the command line (``manus plan``, ``manus reach``): one goal, and
how it is searched for, as a goal motion of :mod:`schemas.goals`.

``--to-pose X Y Z YAW PITCH ROLL`` (the command line's pose, :mod:`manus_stack.pose_args`),
``--to-joints Q1..Q6`` [deg], ``--to NAME`` (a named pose), ``--to-object NAME X Y Z YAW
PITCH ROLL`` (a pose in a scene object's frame), ``--approach MM`` (a straight line along
the gripper's axis; negative: a retreat); ``--free-axis``, ``--tolerance-mm``,
``--tolerance-deg``, ``--seed``, ``--budget``, ``--speed``.
"""

from __future__ import annotations

import argparse
import math

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
from services.planner.errors import refuse

GOAL_OPTIONS = ("to_pose", "to_joints", "to", "to_object", "approach")
"""The goal options (at most one)."""


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
        motion = _goal(args)
        # Decoding checks every field's range, as the planner's queryable will.
        return None if motion is None else type(motion).from_dict(motion.to_dict())
    except ValueError as exc:  # a SchemaError: a field out of its range
        raise refuse("invalid", str(exc)) from exc


def _goal(args: argparse.Namespace) -> Motion | None:
    search = Search(
        seed=args.seed,
        budget=args.budget,
        speed=args.speed,
        interpolation="quintic" if getattr(args, "quintic", False) else "cubic",
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
    return None


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise refuse("invalid", f"--to-object: {text!r} is not a number") from None


def _pose(values: list[float]) -> tuple[list[float], list[float]]:
    return [v * 1e-3 for v in values[:3]], [math.radians(v) for v in values[3:]]
