"""A jog toward the user's head (the controller's jog mode in lock-step with the
simulator): the collision guard slows it and stops it at the person clearance, judged
on the simulator's truth; the jog state names the guard."""

from __future__ import annotations

import itertools

import numpy as np

from manus.collision import CollisionModel
from manus.config import DEFAULT_ARM
from manus.kinematics import fk_position
from manus.scene import default_scene
from manus_stack.jog_lockstep import JogArm
from schemas import endpoints as ep
from schemas.jog import JogLevel, JogRunState, JogState, LimitKind
from services.simulator.config import SimConfig

PERSON_M = default_scene().clearance["person"]


def head_distance(model: CollisionModel, q: np.ndarray) -> float:
    """Smallest distance [m] from any arm body to the head (its clearance added back)."""
    margins = model.margins(q)
    return min(
        float(margins[k]) + c.required for k, c in enumerate(model.checks) if c.other == "head"
    )


def test_a_jog_toward_the_head_slows_and_stops_at_the_clearance_on_the_truth() -> None:
    scene = default_scene()
    head = next(o for o in scene.objects if o.name == "head")
    arm = JogArm(SimConfig(start_pose="unfolded"))
    arm.start()
    assert arm.query(ep.JOG_LEVEL, JogLevel(level=5)).accepted
    arm.run(0.3)
    # Straight at the head's centre, in the arm's base frame, at the fastest level.
    centre = (np.linalg.inv(scene.mount) @ head.body.pose)[:3, 3]
    gripper = fk_position(arm.samples[-1].q, DEFAULT_ARM)
    toward = (centre - gripper) / np.linalg.norm(centre - gripper)
    start = len(arm.samples)
    arm.stream(8.0, units="unitless", linear=list(toward))
    model = CollisionModel(scene, DEFAULT_ARM, opening=arm.ls.sim.truth().gripper)
    distances = [head_distance(model, s.q) for s in arm.samples[start::4]]
    truth = arm.ls.sim.truth()
    # The truth: never touched anything, never within the person clearance of the head,
    # and the arm really came close (the guard stopped it, not something else).
    assert truth.contacts == 0
    assert truth.min_clearance is not None and truth.min_clearance > 0.0
    assert min(distances) >= PERSON_M, min(distances)
    assert min(distances) < PERSON_M + 0.03, min(distances)
    assert all(s.at_rest for s in arm.samples[-20:])  # stopped there, held still
    moved = distances[0] - min(distances)
    assert moved > 0.1  # it did travel toward the head before stopping
    states = [m for m in arm.ls.published(ep.JOG_STATE) if isinstance(m, JogState)]
    guard = [lim for s in states for lim in s.limits if lim.kind == LimitKind.COLLISION]
    assert {lim.object for lim in guard} == {"head"}
    assert any(0.0 < lim.scale < 1.0 for lim in guard)  # slowed on the way
    last = states[-1]
    assert last.state == JogRunState.RUNNING  # still jogging: backing away is allowed
    [stop] = [lim for lim in last.limits if lim.kind == LimitKind.COLLISION]
    assert stop.scale == 0.0 and last.scale == 0.0 and stop.body
    assert PERSON_M <= stop.distance < PERSON_M + 0.03, stop.distance
    words = f"the collision guard: {stop.body} near head (person: keeps 50 mm)"
    assert last.reason == f"stopped by {words}"
    # the words change with the state (slowed, stopped), never with the distances
    changes = sum(a.reason != b.reason for a, b in itertools.pairwise(states))
    assert changes <= 6, [s.reason for s in states]
