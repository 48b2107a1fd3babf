"""A bridge started again numbers its joint states from 0: the controller must answer
them (found by the chaos soak: it took them for old states and went deaf, so a gripper
goal never ended and the sequencer failed the task on its own deadline 35 s later)."""

from __future__ import annotations

from schemas import endpoints as ep
from schemas.control import GripperGoal
from services.controller.config import ControllerConfig
from services.controller.core import ControllerCore
from tests.controller_plant import Plant, ask, steps


def test_states_of_a_restarted_bridge_are_answered_and_end_the_goals() -> None:
    plant = Plant(ControllerCore(ControllerConfig()))
    plant.run(20)
    assert ask(plant.core, ep.GRIPPER_GOAL, GripperGoal(goal_id="grip", opening=0.08)).accepted
    plant.run(5)
    for _ in range(40):  # the bridge dies and a new one starts: 2.4 s without states
        plant.cycle(skip=True)
    plant.seq = 0
    plant.run(3)  # Plant.cycle asserts one command answering each state
    assert [c.ref_seq for c in plant.commands[-3:]] == [0, 1, 2]
    assert all(steps(c) == [0] * 8 for c in plant.commands[-3:])
    (result,) = [r for r in plant.results if r.goal_id == "grip"]
    assert result.status == "aborted" and "joint states interrupted" in result.reason
    assert ask(plant.core, ep.GRIPPER_GOAL, GripperGoal(goal_id="again", opening=0.02)).accepted
    assert plant.run_until_result("again").status == "succeeded"


def test_a_duplicate_or_older_state_is_still_not_answered() -> None:
    plant = Plant(ControllerCore(ControllerConfig()))
    plant.run(5)
    assert plant.core.on_joint_state(plant.states[-1]) == []
    assert plant.core.on_joint_state(plant.states[-3]) == []
