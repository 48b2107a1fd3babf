"""``manus track KEY``: the arm follows a tracker's target until Ctrl-C (docs/follow.md).

    manus track mouth                          # the gripper to 60 mm from the mouth, held
    manus track mouth --offset-mm 0 0 60       # a cup's rim, 60 mm past the gripper
    manus track mouth --standoff-mm 80 --seconds 20
    manus track mouth --close --standoff-mm 30 --close-clearance-mm 20 --offset-mm 0 0 60

KEY is the tracker to follow: the ``source`` of its frames on ``target/pose``. The command
sends a ``FollowGoal`` to ``controller/follow``, prints the controller's ``FollowState``
once a second (state, distance to the standoff point, why it is slowed) and, when the goal
ends, its ``GoalResult`` as one JSON line. Ctrl-C (or ``--seconds``) stops the goal.
Exits 0 when the goal was stopped by this command, 1 when a fault or another source ended
it (its ``cause`` says which), 2 when it was refused or no controller answered.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time

from manus.errors import SchemaError
from manus.node import Node, QueryError
from manus.process import wait_for_signal
from manus.session import settings_from_env
from schemas import endpoints as ep
from schemas.control import EndCause, GoalAck, GoalResult
from schemas.follow import FollowGoal, FollowPhase, FollowState


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The tracker, the goal's settings and the bus settings."""
    parser.add_argument("key", help="the tracker to follow (TargetPose.source on target/pose)")
    parser.add_argument(
        "--standoff-mm", type=float, default=0.0, help="from the target (default: 60 mm)"
    )
    parser.add_argument(
        "--approach",
        type=float,
        nargs=3,
        default=[1.0, 0.0, 0.0],
        metavar=("X", "Y", "Z"),
        help="from the target to the standoff point, in the target's frame (default 1 0 0)",
    )
    parser.add_argument(
        "--offset-mm",
        type=float,
        nargs=3,
        default=[0.0, 0.0, 0.0],
        metavar=("X", "Y", "Z"),
        help="the tracked point in the gripper frame (a held cup's rim: 0 0 60)",
    )
    parser.add_argument(
        "--max-speed-mm-s", type=float, default=0.0, help="speed cap (default: the controller's)"
    )
    parser.add_argument(
        "--close",
        action="store_true",
        help="the closer approach for a user who cannot lean forward (25 mm/s near the target)",
    )
    parser.add_argument(
        "--close-clearance-mm", type=float, default=20.0, help="with --close: the rim's clearance"
    )
    parser.add_argument(
        "--lost-after-ms",
        type=float,
        default=0.0,
        help="the target is lost after this long without a frame (default: two periods)",
    )
    parser.add_argument("--seconds", type=float, help="stop after this long (default: Ctrl-C)")
    parser.add_argument("--goal-id", help="the goal's id (default: track-<time>)")
    parser.add_argument("--connect", nargs="+", metavar="ENDPOINT", help="router endpoint(s)")
    parser.add_argument("--prefix", help="key prefix of the arm (default: manus)")


def goal_of(args: argparse.Namespace) -> FollowGoal:
    """The follow goal the arguments ask for."""
    return FollowGoal(
        goal_id=args.goal_id or f"track-{time.time_ns()}",
        source=args.key,
        standoff=args.standoff_mm / 1000.0,
        approach=[float(v) for v in args.approach],
        offset=[v / 1000.0 for v in args.offset_mm],
        max_speed=args.max_speed_mm_s / 1000.0,
        close=args.close,
        close_clearance=args.close_clearance_mm / 1000.0,
        lost_after=args.lost_after_ms / 1000.0,
    )


def _line(state: FollowState) -> str:
    return (
        f"{state.state}: {state.distance * 1e3:.1f} mm from the standoff point, "
        f"latency {state.latency * 1e3:.0f} ms; {state.reason}"
    )


def run(args: argparse.Namespace) -> int:
    """Follow until stopped; print the result."""
    try:
        goal = goal_of(args)
    except SchemaError as exc:
        sys.stderr.write(f"manus track: {exc}\n")
        return 2
    stop = wait_for_signal()
    settings = settings_from_env(connect=args.connect, prefix=args.prefix)
    ended = threading.Event()
    result: list[GoalResult] = []
    newest: list[FollowState] = []
    with Node("track", settings, liveliness=False) as node:

        def on_state(state: FollowState, _rx: int) -> None:
            if state.goal_id == goal.goal_id:
                newest[:] = [state]

        def on_result(res: GoalResult, _rx: int) -> None:
            if res.goal_id == goal.goal_id:
                result[:] = [res]
                ended.set()

        node.subscribe(node.keys(ep.FOLLOW_STATE), FollowState, on_state, locked=False)
        node.subscribe(node.keys(ep.RESULT), GoalResult, on_result, locked=False)
        try:
            ack = node.query(node.keys(ep.FOLLOW), goal, GoalAck)
        except (QueryError, SchemaError) as exc:
            sys.stderr.write(f"manus track: {exc}\n")
            return 2
        if not ack.accepted:
            sys.stderr.write(f"manus track: refused ({ack.refusal}): {ack.reason}\n")
            return 2
        deadline = None if args.seconds is None else time.monotonic() + args.seconds
        stopped_here = False
        while not ended.is_set():
            if stop.is_set() or (deadline is not None and time.monotonic() >= deadline):
                stopped_here = True
                request = FollowGoal(goal_id=goal.goal_id, stop=True)
                try:
                    node.query(node.keys(ep.FOLLOW), request, GoalAck)
                except (QueryError, SchemaError) as exc:
                    sys.stderr.write(f"manus track: could not stop the goal: {exc}\n")
                    return 1
                ended.wait(2.0)
                break
            ended.wait(1.0)
            if newest and newest[0].state != FollowPhase.ENDED:
                sys.stderr.write(_line(newest[0]) + "\n")
    if result:
        sys.stdout.write(json.dumps(result[0].to_dict()) + "\n")
        return 0 if result[0].cause == EndCause.CANCEL_REQUEST and stopped_here else 1
    sys.stderr.write("manus track: no result for the goal\n")
    return 1
