"""The objects in lock-step: the simulator's camera publishes, the planner's world model
follows on ``planner/objects``; a hidden object goes stale, a removed one goes, and a
follower of the updates holds what the planner holds."""

from __future__ import annotations

import numpy as np
import pytest

from manus.scene import pose_matrix
from manus.world import WorldModel
from manus.world_follower import apply_update
from manus_stack.lockstep import LockStep
from schemas import endpoints as ep
from schemas.objects import WorldObject, WorldUpdate
from services.planner.config import PlannerConfig
from services.planner.core import PlannerCore
from services.planner.wiring import WIRING as PLANNER
from services.simulator.config import SimConfig
from services.simulator.objects import SimObject

S = 1_000_000_000


def stack(seed: int = 0) -> tuple[LockStep, PlannerCore]:
    ls = LockStep(SimConfig(start_pose="unfolded", objects="default", seed=seed))
    planner = PlannerCore(PlannerConfig())
    ls.attach(PLANNER, planner)
    return ls, planner


def follow(updates: list[WorldUpdate]) -> tuple[dict[str, WorldObject], int]:
    held: dict[str, WorldObject] = {}
    version = 0
    for update in updates:
        held = apply_update(held, version, update)
        version = update.version
    return held, version


def updates(ls: LockStep) -> list[WorldUpdate]:
    return [m for m in ls.published(ep.OBJECTS) if isinstance(m, WorldUpdate)]


def test_the_world_model_follows_the_camera_never_the_truth() -> None:
    ls, planner = stack()
    ls.run_for(3.0)
    world = planner.world
    truth = {o.id: o for o in ls.sim.truth().objects}
    assert sorted(world.objects) == sorted(truth) == ["bottle", "cup", "phone"]
    for name, obj in world.objects.items():
        assert obj.source == "camera" and not obj.stale
        assert 0.0 < np.linalg.norm(np.subtract(obj.xyz, truth[name].xyz)) < 0.02, name
        assert world.age_s(name) < 0.5
    # The world model's time is the newest frame's capture: on the stack's clock.
    assert world.now_ns is not None and 0 <= ls.t_ns - world.now_ns < 0.25 * S
    assert follow(updates(ls)) == (world.objects, world.version)

    # A box stood on the table between the camera and the cup hides it: it goes stale.
    camera = np.array(ls.sim.config.camera.xyz_mm) * 1e-3
    cup = np.array(truth["cup"].xyz)
    front = camera + (cup - camera) * (0.85 - camera[0]) / (cup[0] - camera[0])  # x = 0.85
    box = SimObject("box", "cereal", "box", (0.1, 0.2, 0.3), pose_matrix(list(front), (0, 0, 0)))
    ls.sim.objects.add(box)
    hidden_at = ls.t_ns
    ls.run_for(3.0)
    assert sorted(world.objects) == ["bottle", "box", "cup", "phone"]
    assert world.objects["cup"].stale and not world.objects["bottle"].stale
    assert world.age_s("cup") > 2.0
    assert world.objects["cup"].stamp_ns <= hidden_at + 0.2 * S
    assert "was last observed" in world.stale_reason("cup")

    # The bottle leaves the simulator: the camera says so, the world model drops it.
    ls.sim.objects.remove("bottle")
    ls.run_for(0.5)
    assert "bottle" not in world.objects
    assert follow(updates(ls)) == (world.objects, world.version)


def test_lock_step_runs_with_objects_repeat_exactly() -> None:
    def run(seed: int) -> list[WorldUpdate]:
        ls, _ = stack(seed)
        ls.run_for(2.0)
        return updates(ls)

    first = run(1)
    assert first and first == run(1)
    assert first != run(2)  # another seed: other noise


def test_a_planner_world_model_only_speaks_once_perception_does() -> None:
    ls = LockStep(SimConfig(start_pose="unfolded", objects="none"))
    ls.sim.camera = None  # no perception at all
    planner = PlannerCore(PlannerConfig())
    ls.attach(PLANNER, planner)
    ls.run_for(2.0)
    assert ls.published(ep.OBJECTS) == [] and planner.world.objects == {}
    assert isinstance(planner.world, WorldModel) and planner.world.version == 0


@pytest.mark.parametrize("objects", ["none", "default"])
def test_an_empty_or_full_table_in_perception_frames(objects: str) -> None:
    ls = LockStep(SimConfig(start_pose="unfolded", objects=objects))
    ls.run_for(1.0)
    frames = ls.published(ep.PERCEPTION)
    assert len(frames) >= 8
    assert all(len(getattr(f, "objects", [])) <= (0 if objects == "none" else 3) for f in frames)
