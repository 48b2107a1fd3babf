"""The collision model and the planner's check: thesis paths pass, a path through the
user's head or into the table is refused with where, the sweep decides as a dense
check does on seeded random paths."""

from __future__ import annotations

import math
from pathlib import Path as FilePath

import numpy as np
import pytest

from manus.collision import CollisionModel
from manus.collision_pairs import SELF_PAIRS
from manus.config import DEFAULT_ARM, FOLDED_Q_DEG, UNFOLDED_Q_DEG
from manus.scene import default_scene
from manus.sweep import TOLERANCE_M, sweep
from manus.viapoints import load_path, parse_viapoints
from schemas.planning import PlanReply, PlanRequest, ViaPointPath
from services.planner.config import PlannerConfig
from services.planner.core import PlannerCore
from services.planner.spline import PiecewisePolynomial

ROOT = FilePath(__file__).resolve().parent.parent
UNFOLDED = [math.radians(v) for v in UNFOLDED_Q_DEG]
CORE = PlannerCore()
MODEL = CollisionModel(default_scene(), DEFAULT_ARM)


def moves(*steps: tuple[float, ...]) -> str:
    """A via-point file: the start, then relative (type 2) moves of (dx, dy, dz [mm],
    d_yaw, d_roll, d_pitch [deg]) 3 s apart."""
    rows = ["0 0 0 0 0 0 0 0 0 0 0 0 0 2"]
    for i, step in enumerate(steps, start=1):
        dx, dy, dz, *angles = (*step, 0.0, 0.0, 0.0)[:6]
        yaw, roll, pitch = angles
        rows.append(f"{dx} {dy} {dz} 0 0 0 {yaw} {roll} {pitch} 0 0 0 {3.0 * i} 2")
    return "\n".join(rows) + "\n"


def plan(text: str, source: str = "test.txt") -> PlanReply:
    path = parse_viapoints(text, source)
    return CORE.plan(
        PlanRequest(ViaPointPath(path=path, speed_scaling=True), start=UNFOLDED, preview_dt=0.0)
    )


@pytest.mark.parametrize("name", ["thesis_square.txt", "thesis_circle.txt"])
@pytest.mark.parametrize("interpolation", ["cubic", "quintic"])
def test_thesis_paths_are_clear_of_the_default_scene(name: str, interpolation: str) -> None:
    path = load_path(ROOT / "paths" / name)
    reply = CORE.plan(
        PlanRequest(ViaPointPath(path=path, interpolation=interpolation), start=UNFOLDED)
    )
    assert reply.ok, reply.error
    assert reply.trajectory is not None
    clearance = reply.trajectory.clearance
    assert clearance is not None and clearance.distance > clearance.required
    assert reply.trajectory.scene_version == 0


def test_a_path_through_the_users_head_is_refused_naming_the_head() -> None:
    # From the unfolded pose to the head's centre, (-578, 315, 30) mm away.
    reply = plan(moves((-289, 157, 15), (-289, 158, 15)))
    assert not reply.ok and reply.error is not None
    error = reply.error
    assert error.reason == "collision"
    assert "from head (person: needs 50 mm)" in error.message
    assert error.message.startswith(
        "between test.txt line 2 (via point 1) and line 3 (via point 2): at t = "
    )
    assert (error.via_point, error.line) == (2, 3)
    assert error.value is not None and error.value < 0.05
    assert error.limit == pytest.approx(0.05)


def test_a_path_that_clips_the_table_is_refused() -> None:
    # Forward and down, pitching the gripper: the forearm reaches the table's edge.
    reply = plan(moves((140, 0, -110, 0, 0, 15), (140, 0, -110, 0, 0, 15)))
    assert not reply.ok and reply.error is not None
    assert reply.error.reason == "collision"
    assert "from table (environment: needs 15 mm)" in reply.error.message
    # The same path without the scene plans.
    bare = PlannerCore(PlannerConfig(scene="none"))
    path = parse_viapoints(moves((140, 0, -110, 0, 0, 15), (140, 0, -110, 0, 0, 15)), "t")
    assert bare.plan(PlanRequest(ViaPointPath(path=path, speed_scaling=True), start=UNFOLDED)).ok


def test_plan_names_the_scene_and_its_version() -> None:
    reply = plan(moves((-289, 157, 15), (-289, 158, 15)))
    assert reply.error is not None
    assert f"(scene version 0: {default_scene().source})" in reply.error.message


def test_self_pairs_are_declared_once_and_exist() -> None:
    names = {s.name for s in MODEL.shapes}
    assert all(a in names and b in names for a, b in SELF_PAIRS)
    assert len(set(SELF_PAIRS)) == len(SELF_PAIRS)
    assert [c for c in MODEL.checks if c.cls == "self"] == [
        c for c in MODEL.checks if (c.body, c.other) in SELF_PAIRS
    ]


def test_gripper_box_follows_the_opening() -> None:
    model = CollisionModel(default_scene(), DEFAULT_ARM, opening=0.0)
    q = np.radians(FOLDED_Q_DEG)
    closed = model.margins(q)
    model.set_opening(0.09)
    assert model.opening == pytest.approx(0.09)
    opened = model.margins(q)
    assert (opened <= closed + 1e-5).all()  # GJK's tolerance
    assert (closed - opened).max() > 0.03


def test_margins_are_distance_minus_clearance() -> None:
    q = np.radians(UNFOLDED_Q_DEG)
    found = MODEL.clearance(q)
    assert found.distance == pytest.approx(found.margin + found.check.required)
    k, margin = MODEL.tightest(q)
    assert MODEL.probe(q).best.margin == pytest.approx(min(margin, found.margin), abs=1e-6)
    assert margin == pytest.approx(MODEL.margins(q).min())
    assert (
        MODEL.checks[k]
        == min(zip(MODEL.margins(q), MODEL.checks, strict=True), key=lambda mc: mc[0])[1]
    )


def random_paths(count: int, seed: int) -> list[PiecewisePolynomial]:
    """Seeded joint-space cubic paths from the unfolded pose: 1-3 moves of up to 60 deg
    per joint, 2 s each, at rest at every knot (many pass near the scene, some through)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        n = int(rng.integers(1, 4))
        steps = np.radians(rng.uniform(-60.0, 60.0, (n, 6)))
        q = np.array(UNFOLDED) + np.vstack((np.zeros(6), np.cumsum(steps, axis=0)))
        times = np.arange(n + 1) * 2.0
        out.append(PiecewisePolynomial.hermite(times, q, np.zeros_like(q)))
    return out


def test_the_sweep_decides_as_a_dense_check_on_random_paths() -> None:
    """Against margins computed every 4 ms (under 2 mm of any point's travel) by the
    model's plain per-configuration query: the same accept / refuse decision on every
    path, a violation where the dense check has one, and a reported smallest margin that
    is a real configuration's and at most TOLERANCE_M above the dense one."""
    accepted = refused = 0
    for curve in random_paths(30, seed=17):
        ex = curve.extremes(1)
        swept = sweep(MODEL, curve.times, np.maximum(-ex.low, ex.high), curve.evaluate)
        dense = curve.evaluate(np.arange(0.0, curve.duration + 1e-9, 0.004))
        lowest = min(MODEL.clearance(q).margin for q in dense)
        assert (swept.violation is None) == (lowest >= 0.0), (swept, lowest)
        assert MODEL.clearance(swept.worst.q).margin == pytest.approx(swept.worst.margin, abs=1e-6)
        if swept.violation is None:
            accepted += 1
            assert lowest - 0.001 <= swept.worst.margin <= lowest + TOLERANCE_M
        else:
            refused += 1
            assert swept.violation.margin < 0.0
    assert accepted >= 15 and refused >= 5  # both decisions are exercised


def validate(task_words: list[str], start_deg: tuple[float, ...]) -> list[str]:
    """Validate ``manus run --fold-out WORDS --fold-in`` from ``start_deg`` as the
    sequencer does."""
    from services.sequencer.run_cli import with_folds
    from services.sequencer.taskfile import task_from_args
    from services.sequencer.validate import Validator, fold_checker

    task = with_folds(task_from_args(task_words), fold_out=True, fold_in=True)
    start = [math.radians(a) for a in start_deg]
    v = Validator(task, start, DEFAULT_ARM, fold_checker("default", DEFAULT_ARM))
    while (request := v.next_request()) is not None:
        v.on_reply(CORE.plan(request))
    return v.errors


def test_a_fold_out_that_would_hit_the_armrest_is_refused() -> None:
    square = str(ROOT / "paths" / "thesis_square.txt")
    # The demo's task: fold out from the folded pose, the square, fold in.
    assert validate([square, "40"], FOLDED_Q_DEG) == []
    # Reaching back over the right armrest: folding out from there swings the upper
    # arm through it (the arm's fold is a straight line in joint space).
    errors = validate([square], (157.0, 59.0, -81.0, -69.0, -92.0, 0.0))
    assert len(errors) == 1, errors
    assert errors[0].startswith(
        "--fold-out: step 1 (fold_out): fold out from (157, 59, -81, -69, -92, 0) "
        "deg would bring the upper_arm "
    )
    assert "from armrest_right (chair: needs 15 mm)" in errors[0]


ZONES = """\
version: 1
mount: {xyz_mm: [350, -420, 1000]}
objects: []
zones:
  - {name: box, kind: keep_in, shape: box, size_mm: [2000, 2000, 2000], xyz_mm: [350, -420, 1000]}
  - {name: cup_area, kind: keep_out, links: gripper, shape: sphere, radius_mm: 60,
     xyz_mm: [558, -315, 1200]}
"""
"""A keep-out sphere around the unfolded gripper (for the gripper only) and a big box."""


def test_zones_keep_the_gripper_out_and_the_arm_in() -> None:
    from manus.scene import parse_scene

    scene = parse_scene(ZONES, "zones.yaml")
    model = CollisionModel(scene, DEFAULT_ARM)
    unfolded = np.radians(UNFOLDED_Q_DEG)
    found = model.clearance(unfolded)
    assert found.margin < 0 and found.check.other == "cup_area"
    assert found.check.body in ("gripper", "gripper_motor") and found.check.cls == "zone"
    # links: gripper: the other bodies are not checked against it.
    assert {c.body for c in model.checks if c.other == "cup_area"} == {"gripper", "gripper_motor"}
    # The keep-in box shrunk around the shoulder: the arm is outside it.
    tight = parse_scene(ZONES.replace("[2000, 2000, 2000]", "[600, 600, 600]"), "zones.yaml")
    inside = CollisionModel(tight, DEFAULT_ARM).keep_in_margins()
    model_tight = CollisionModel(tight, DEFAULT_ARM)
    model_tight.margins(unfolded)
    ((margin, check),) = model_tight.keep_in_margins()
    assert margin < 0 and check.other == "keep_in box" and check.body != ""
    assert len(inside) == 1


def test_the_sequencer_refuses_a_task_whose_move_would_hit_the_head(tmp_path: FilePath) -> None:
    head = tmp_path / "head.txt"
    head.write_text(moves((-289, 157, 15), (-289, 158, 15)))
    square = str(ROOT / "paths" / "thesis_square.txt")
    errors = validate([square, "40", str(head)], FOLDED_Q_DEG)
    assert len(errors) == 1, errors
    assert errors[0].startswith(f"{head}: step 4 (move): planner refused (collision): between ")
    assert "from head (person: needs 50 mm)" in errors[0]


def test_manus_plan_prints_the_smallest_clearance_and_where(
    capsys: pytest.CaptureFixture[str],
) -> None:
    import json

    from manus_stack.cli import main

    assert main(["plan", str(ROOT / "paths" / "thesis_circle.txt")]) == 0
    out, err = capsys.readouterr()
    clearance = json.loads(out)["clearance"]
    assert clearance["other"] == "table" and clearance["class"] == "environment"
    assert clearance["distance_mm"] > clearance["required_mm"] == 15.0
    assert err.startswith(f"smallest clearance: {clearance['body']} ")
    assert f"from table (environment: needs 15 mm) at t = {clearance['time_s']:.2f} s" in err
    assert main(["plan", str(ROOT / "paths" / "thesis_circle.txt"), "--scene", "none"]) == 0
    assert json.loads(capsys.readouterr().out)["clearance"] is None


def test_pairs_set_aside_for_a_motion_only_lower_the_margins() -> None:
    """The sweep asks Coal only for the pairs that can come near the motion's boxes:
    every body's margin is then at most its true one (never optimistic), the true one
    wherever something kept is within reach, and the tightest check is unchanged
    while it is a kept pair; every pair is back afterwards."""
    from manus.sweep import NEAR_M, _Motion

    curve = random_paths(1, seed=3)[0]
    ex = curve.extremes(1)
    motion = _Motion(MODEL, curve.times, np.maximum(-ex.low, ex.high), curve.evaluate)
    lo, hi = motion.boxes()
    qs = curve.evaluate(np.linspace(0.0, curve.duration, 25))
    full = [MODEL.pair_margins(q) for q in qs]
    aside = MODEL.restrict(lo, hi, NEAR_M)
    try:
        assert np.isfinite(aside).any() and (aside >= NEAR_M).all()
        restricted = [MODEL.pair_margins(q) for q in qs]
    finally:
        MODEL.unrestrict()
    for (free, tight, row), (r_free, r_tight, r_row) in zip(full, restricted, strict=True):
        assert (r_free <= free + 1e-6).all()  # GJK warm starts differ by ~1e-7
        near = free < aside
        assert r_free[near] == pytest.approx(free[near], abs=1e-6)
        if tight < aside.min():
            assert r_row == row and r_tight == pytest.approx(tight, abs=1e-6)
    assert [MODEL.pair_margins(q)[2] for q in qs] == [f[2] for f in full]
