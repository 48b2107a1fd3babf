"""The controller shell on a loopback router: commands answer joint states, goals run."""

from __future__ import annotations

import queue

from manus.node import Node, QueryError
from manus.session import ZenohSettings
from schemas import endpoints as ep
from schemas.commands import JointVelocityCommand
from schemas.control import CancelGoal, GoalAck, GoalResult, TrajectoryGoal
from schemas.state import JointState
from services.controller.core import ControllerCore
from services.controller.shell import ControllerShell
from tests.conftest import eventually
from tests.controller_plant import Q0, Plant, line_trajectory, steps


def test_controller_shell_runs_a_goal_over_zenoh(zenoh_settings: ZenohSettings) -> None:
    commands: queue.Queue[JointVelocityCommand] = queue.Queue()
    results: queue.Queue[GoalResult] = queue.Queue()
    # The plant's own core is unused: the commands come back over the bus.
    plant = Plant(ControllerCore())
    with (
        ControllerShell(zenoh_settings) as shell,
        Node("test_arm", zenoh_settings, liveliness=False) as arm,
    ):
        keys = arm.keys
        arm.subscribe(keys(ep.JOINT_VELOCITY), JointVelocityCommand, lambda m, t: commands.put(m))
        arm.subscribe(keys(ep.RESULT), GoalResult, lambda m, t: results.put(m))
        joints = arm.publisher(keys(ep.JOINTS))

        def answered() -> bool:
            joints.put(plant.joint_state())
            plant.seq += 1  # each try is a new state (a repeated seq is not answered)
            try:
                commands.get(timeout=0.2)
            except queue.Empty:
                return False
            return True

        eventually(answered)
        assert "controller" in arm.alive_services()

        def cycle() -> JointVelocityCommand:
            js: JointState = plant.joint_state()
            joints.put(js)
            while True:
                cmd = commands.get(timeout=5.0)
                if cmd.ref_seq == js.seq:
                    break
            assert True
            plant.pending = list(steps(cmd))
            plant.cycle(skip=True)
            plant.active = list(steps(cmd))
            return cmd

        first = cycle()
        assert steps(first) == [0] * 8 and first.source == "controller"

        def ask_goal() -> GoalAck:
            goal = TrajectoryGoal(
                goal_id="z1", trajectory=line_trajectory(Q0, (5, 0, 0, 0, 0, 0), 1.0)
            )
            return arm.query(keys(ep.GOAL), goal, GoalAck)

        ack = ask_goal()
        assert ack.accepted, ack.reason
        refused = arm.query(keys(ep.CANCEL), CancelGoal(goal_id="other"), GoalAck)
        assert not refused.accepted and "other" in refused.reason
        moved = False
        for _ in range(60):
            counts = steps(cycle()) or []
            moved = moved or any(counts)
            if not results.empty():
                break
        result = results.get(timeout=5.0)
        assert moved and result.goal_id == "z1" and result.status == "succeeded", result.reason
        with shell.node.lock:
            assert shell.sent["controller/result"] == 1
            assert shell.sent["controller/feedback"] > 10

        _assert_malformed_goal_refused(arm)


def _assert_malformed_goal_refused(arm: Node) -> None:
    """A request that is not a TrajectoryGoal gets an error reply naming the queryable."""
    try:
        arm.query(
            arm.keys("controller/goal"),
            JointVelocityCommand(
                stamp_ns=0,
                seq=0,
                source="x",
                ref_seq=-1,
                velocity=[0.0] * 6,
                gripper_velocity=0.0,
            ),
            GoalAck,
            timeout=2.0,
        )
    except QueryError as exc:
        assert "controller/goal" in str(exc)
    else:
        raise AssertionError("a malformed goal must get an error reply")
