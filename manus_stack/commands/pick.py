"""``manus pick OBJECT``, ``manus place OBJECT --at X Y Z YAW PITCH ROLL`` or ``--on
SURFACE``, ``manus give OBJECT``: an object task on the live stack (docs/pick.md).

The object is the world model's (its id, as perception reports it: ``cup``). The step
becomes a task of one ``pick``, ``place`` or ``give`` step, submitted to the sequencer
(:func:`services.sequencer.run_cli.submit_and_follow`, as ``manus run`` does): it plans
every stage before anything moves (a refusal names the object and the reason, exit 2),
then runs it. ``--at`` is the object's centre in the chair frame [mm] and its yaw, pitch
and roll [deg] (objects rest upright: pitch and roll 0). Exit codes as ``manus run``'s.
"""

from __future__ import annotations

import argparse
import math

from schemas.sequencing import StepKind, Task, TaskStep
from services.sequencer.run_cli import add_bus_arguments, submit_and_follow


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``OBJECT``, ``--mode`` and the bus settings."""
    add_object_arguments(parser)


def add_object_arguments(parser: argparse.ArgumentParser) -> None:
    """The arguments every object command takes."""
    parser.add_argument("object", help="the object's id in the world model (e.g. cup)")
    parser.add_argument(
        "--mode",
        dest="control_mode",
        choices=("default", "thesis"),
        default="default",
        help="controller mode (default: default)",
    )
    add_bus_arguments(parser)


def add_place_arguments(parser: argparse.ArgumentParser) -> None:
    """``OBJECT``, ``--at`` or ``--on``, ``--mode`` and the bus settings."""
    add_object_arguments(parser)
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument(
        "--at",
        nargs=6,
        type=float,
        metavar=("X", "Y", "Z", "YAW", "PITCH", "ROLL"),
        help="the object's centre, chair frame [mm], and orientation [deg]",
    )
    where.add_argument("--on", metavar="SURFACE", help="a scene object to put it on")


def step_of(args: argparse.Namespace, kind: StepKind, command: str) -> TaskStep:
    """The task step the arguments ask for."""
    at = getattr(args, "at", None)
    pose = None
    if at is not None:
        pose = [v * 1e-3 for v in at[:3]] + [math.radians(v) for v in at[3:]]
    return TaskStep(
        kind=kind, object=args.object, at=pose, surface=getattr(args, "on", None) or "",
        where=command,
    )  # fmt: skip


def run_step(args: argparse.Namespace, kind: StepKind) -> int:
    """Submit the one-step task and follow it."""
    command = f"manus {kind}"
    task = Task(
        steps=[step_of(args, kind, command)], name=f"{kind} {args.object}", mode=args.control_mode
    )
    return submit_and_follow(task, args, command)


def run(args: argparse.Namespace) -> int:
    """Pick the object."""
    return run_step(args, StepKind.PICK)
