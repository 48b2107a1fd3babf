"""``manus reach GOAL`` and ``manus move-to NAME``: a goal run on the live stack.

The goal (:mod:`manus_stack.goal_args`: ``--to-pose X Y Z YAW PITCH ROLL``,
``--to-joints``, ``--to NAME``, ``--to-object``, ``--approach MM``; ``move-to NAME`` is
``reach --to NAME``) becomes a task of one ``reach`` step, submitted to the sequencer
(:func:`services.sequencer.run_cli.submit_and_follow`, as ``manus run`` does): the
sequencer plans it before anything moves (a refusal names the reason, exit 2), the live
view (``manus view``) draws the plan, then the controller runs it. Exit codes as
``manus run``'s.
"""

from __future__ import annotations

import argparse

from manus_stack.goal_args import add_goal_arguments, goal_from_args
from schemas.goals import NamedGoal, Search
from schemas.motion import Motion
from schemas.sequencing import StepKind, Task, TaskStep
from services.planner.errors import refuse
from services.sequencer.run_cli import add_bus_arguments, submit_and_follow


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The goal, ``--mode`` and the bus settings."""
    add_goal_arguments(parser)
    _add_common(parser)


def add_move_to_arguments(parser: argparse.ArgumentParser) -> None:
    """``NAME``, the search's seed and speed, ``--mode`` and the bus settings."""
    parser.add_argument("name", help="a named pose (home, drink, folded, unfolded, ...)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the search (default 1)")
    parser.add_argument(
        "--speed",
        type=float,
        default=0.5,
        help="fraction of the joint speed and acceleration limits to use (default 0.5)",
    )
    _add_common(parser)


def _add_common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--mode",
        dest="control_mode",
        choices=("default", "thesis"),
        default="default",
        help="controller mode (default: default)",
    )
    add_bus_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Run the goal the options name on the stack."""
    goal = goal_from_args(args)
    if goal is None:
        raise refuse(
            "invalid", "give a goal (--to-pose, --to-joints, --to, --to-object, --approach)"
        )
    return run_goal(goal, args, "manus reach")


def run_move_to(args: argparse.Namespace) -> int:
    """Move to the named pose ``args.name`` on the stack."""
    goal = NamedGoal(name=args.name, search=Search(seed=args.seed, speed=args.speed))
    return run_goal(goal, args, "manus move-to")


def run_goal(goal: Motion, args: argparse.Namespace, command: str) -> int:
    """A task of one reach step, submitted and followed."""
    what = getattr(goal, "name", "") or str(getattr(goal, "kind", "goal"))
    step = TaskStep(kind=StepKind.REACH, goal=goal, where=command)
    task = Task(
        steps=[step], name=f"{command.rsplit(maxsplit=1)[-1]} {what}", mode=args.control_mode
    )
    return submit_and_follow(task, args, command)
