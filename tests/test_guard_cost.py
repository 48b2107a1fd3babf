"""What makes the controller's guard cheaper changes none of its answers: a core whose
collision model another core used before publishes the same bytes as one with a new
model, and the goal's clearance report that asks Coal for fewer bodies reports what
asking every body reports."""

from __future__ import annotations

import gc
import math
from pathlib import Path

import numpy as np
import pytest

from manus.collision import CollisionModel
from manus.config import DEFAULT_ARM
from manus.held import HeldBody
from manus.scene import default_scene
from manus.validity import checker_for
from manus_stack.controlled import controller_input
from manus_stack.recordings import record_thesis_runs
from services.controller import run_guard as guard_module
from services.controller.core import ControllerCore
from services.controller.guard import Guard
from services.controller.wiring import WIRING as CONTROLLER
from services.recorder.reading import Recording, decode


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A lock-step recording of the thesis square (the guard anchors, reports and
    follows the gripper's opening in it)."""
    path = tmp_path_factory.mktemp("guard-cost") / "square.mcap"
    record_thesis_runs(["square"], path)
    return path


def replay(path: Path, core: ControllerCore) -> list[bytes]:
    """Every message ``core`` publishes for the recorded inputs, encoded."""
    inputs = [(r.suffix, decode(r)) for r in Recording(path).messages(CONTROLLER.input_suffixes)]
    out: list[bytes] = []
    for suffix, msg in inputs:
        out += [suffix.encode() + m.encode() for suffix, m in controller_input(core, suffix, msg)]
    return out


def test_a_core_after_another_publishes_the_bytes_of_a_core_with_a_new_model(
    recording: Path,
) -> None:
    gc.collect()  # the cores of the recording gone, their models in the spares
    guard_module._SPARE.clear()
    first = ControllerCore()
    fresh = replay(recording, first)
    assert first.guard is not None
    used = first.guard.guard.model
    assert used.opening != DEFAULT_ARM.gripper_max  # the replay changed what it was built with
    # Left 3 mm wider than the arm's gripper: within what the guard lets pass unchanged.
    used.set_opening(used.opening + 0.003)
    del first  # gone at once (no cycle): its model is the spare
    second = ControllerCore()
    assert second.guard is not None and second.guard.guard.model is used  # used again
    assert used.opening == DEFAULT_ARM.gripper_max  # as a new one is built
    assert replay(recording, second) == fresh


def test_a_model_with_a_moved_object_is_not_used_again() -> None:
    gc.collect()
    guard_module._SPARE.clear()
    core = ControllerCore()
    assert core.guard is not None
    model = core.guard.guard.model
    person = next(o for o in default_scene().objects if o.name == "head")
    pose = person.body.pose.copy()
    pose[0, 3] += 0.01
    core.move_object("head", pose)
    del core
    other = ControllerCore()
    assert other.guard is not None and other.guard.guard.model is not model


LOW = np.radians([-170.0, -80.0, -150.0, -170.0, -110.0, -170.0])
"""The low ends of the joint ranges the seeded configurations are drawn from [rad]."""

HELD = {
    "nothing": (),
    "cup": (HeldBody("cup", "cup", "cylinder", (0.035, 0.1), (0.0, 0.0, 0.08), (0.0,) * 3),),
    # Across the fingers, past both sides: nearer the arm's other bodies than the cup.
    "rod": (HeldBody("rod", "rod", "capsule", (0.02, 0.35), (0.0, 0.02, 0.0), (0.0, 0.0, 1.5708)),),
}


@pytest.mark.parametrize("held", sorted(HELD))
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_report_of_fewer_bodies_is_the_report_of_all(seed: int, held: str) -> None:
    """Also with a held body: the arm's bodies are skipped by their fast margins as
    without one; the held body's pair with the gripper motor (on its own joint) no
    margin bounds, so it is always computed."""
    rng = np.random.default_rng(seed)
    guard = Guard(CollisionModel(default_scene(), DEFAULT_ARM, held=HELD[held]))
    model = guard.model
    assert model.rigid.any() == bool(HELD[held])  # each has a pair with the gripper motor
    compared = 0
    for _ in range(60):
        q = rng.uniform(LOW, -LOW)
        guard.advance.anchor_fast(q)
        full = model.probe(q, reach=False).best
        for below in (math.inf, full.margin + 1e-3, full.margin, full.margin - 1e-3,
                      full.margin + 0.05, float(rng.uniform(-0.05, 0.3))):  # fmt: skip
            guard.report_below = below
            got = guard._report(q)
            if guard.advance.margin >= below:
                assert got is None
            elif full.margin < below:
                assert got is not None
                assert (got.margin, got.check) == (full.margin, full.check)
                compared += 1
            else:
                assert got is None or got.margin >= below - 1e-6
    assert compared > 50


def test_the_fast_check_for_an_opening_seen_before_answers_as_one_built_for_it() -> None:
    rng = np.random.default_rng(4)
    Q = rng.uniform(LOW, -LOW, size=(40, 6))
    used = CollisionModel(default_scene(), DEFAULT_ARM)
    checker = checker_for(used)
    for opening in (0.03, DEFAULT_ARM.gripper_max, 0.03):  # the last two: kept arrays
        used.set_opening(opening)
        fresh = checker_for(CollisionModel(default_scene(), DEFAULT_ARM, opening=opening))
        for q in Q:
            got, want = checker.margins(q), fresh.margins(q)
            assert got.tight == want.tight and got.check == want.check
            assert np.array_equal(got.free, want.free)
        assert np.array_equal(checker.is_valid_batch(Q), fresh.is_valid_batch(Q))


def test_a_held_bodys_pair_on_its_own_joint_is_reported_though_no_margin_bounds_it() -> None:
    # A ball held 10 mm (margin) from the gripper motor, which shares its joint: that
    # margin never changes, so no fast margin of the ball's travel includes it.
    ball = HeldBody("ball", "ball", "sphere", (0.02,), (0.0, 0.0, -0.05), (0.0,) * 3)
    guard = Guard(CollisionModel(default_scene(), DEFAULT_ARM, held=(ball,)))
    model = guard.model
    rng = np.random.default_rng(4)
    held_skippable = 0
    for _ in range(40):
        q = rng.uniform(LOW, -LOW)
        guard.advance.anchor_fast(q)
        full = model.probe(q, reach=False).best
        if full.check.other != "gripper_motor" or guard.advance.margin >= full.margin + 1e-3:
            continue
        guard.report_below = full.margin + 1e-3
        held_skippable += bool(guard.advance.free[-1] >= guard.report_below + 1e-6)
        got = guard._report(q)
        assert got is not None and (got.margin, got.check) == (full.margin, full.check)
    assert held_skippable > 10


def test_a_cover_point_moves_no_further_than_its_levers_say() -> None:
    model = CollisionModel(default_scene(), DEFAULT_ARM)
    cover, levers = model.cover, model.cover.levers()
    rng = np.random.default_rng(5)
    position = {b: k for k, b in enumerate(cover.moving)}
    for _ in range(200):
        q0 = rng.uniform(LOW, -LOW)
        q1 = q0 + rng.normal(0.0, 0.3, 6)
        model.probe(q0, reach=False)
        p0 = cover.world(model.data)
        model.probe(q1, reach=False)
        moved = np.linalg.norm(cover.world(model.data) - p0, axis=1)
        bound = np.abs(q1 - q0) @ levers
        for i, body in enumerate(cover.point_body):
            if int(body) in position:
                assert moved[i] <= bound[position[int(body)]] + 1e-9
            else:  # a body on the base (column, shoulder) never moves
                assert moved[i] == 0.0


def test_a_report_that_leaves_the_keep_in_zones_out_reports_what_one_with_them_does() -> None:
    # Along a walk of small steps: the zones are left out where their margin where
    # last computed, less how far any cover point can have moved, is over the bound.
    guard = Guard(CollisionModel(default_scene(), DEFAULT_ARM))
    model = guard.model
    rng = np.random.default_rng(6)
    q = np.radians([0.0, 30.0, -60.0, 0.0, 40.0, 0.0])
    left_out = compared = 0
    for _ in range(300):
        q = q + rng.normal(0.0, 0.02, 6)
        guard.advance.anchor_fast(q)
        full = model.probe(q).best
        below = full.margin + float(rng.choice([1e-3, 0.02, -1e-3]))
        guard.report_below = below
        at = guard._zones_at
        left_out += at is not None and at[1] - guard._travel(q, at[0]) >= below + 1e-6
        got = guard._report(q)
        if guard.advance.margin < below and full.margin < below:
            assert got is not None
            assert (got.margin, got.distance, got.check) == (full.margin, full.distance, full.check)
            compared += 1
        elif guard.advance.margin < below:
            assert got is None or got.margin >= below - 1e-6
    assert left_out > 100 and compared > 100
