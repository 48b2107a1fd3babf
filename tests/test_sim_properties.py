"""Properties of the drive maths and of the simulator under arbitrary command sequences."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from manus.protocol import FrameId, MoveCommand, decode_status, move_frame
from services.simulator.config import SimConfig
from services.simulator.core import SimCore
from services.simulator.drives import backlash, lag_step, move_toward
from services.simulator.scripted import ScriptedPc
from services.simulator.workspace import area_violation, stretch_violation

speeds = st.floats(-60.0, 60.0)
times = st.floats(0.0, 0.1)


@given(st.floats(-100, 100), speeds, speeds, times, times, st.floats(0.0, 0.05))
def test_lag_step_composes_exactly(
    x: float, v: float, u: float, dt1: float, dt2: float, tau: float
) -> None:
    a = np.array([x]), np.array([v]), np.array([u])
    x1, v1 = lag_step(*a, dt1, tau)
    x2, v2 = lag_step(x1, v1, a[2], dt2, tau)
    x3, v3 = lag_step(*a, dt1 + dt2, tau)
    assert math.isclose(float(x2[0]), float(x3[0]), abs_tol=1e-9)
    assert math.isclose(float(v2[0]), float(v3[0]), abs_tol=1e-9)


@given(speeds, speeds, st.floats(0.001, 0.05))
def test_lag_step_moves_monotonically_toward_the_target_speed(
    v: float, u: float, tau: float
) -> None:
    _, v1 = lag_step(np.zeros(1), np.array([v]), np.array([u]), 0.02, tau)
    assert abs(float(v1[0]) - u) <= abs(v - u) + 1e-12


@given(
    st.lists(st.floats(-5, 5), min_size=1, max_size=40),
    st.floats(0.0, 1.0),
)
def test_backlash_keeps_the_output_within_half_the_band(moves: list[float], width: float) -> None:
    w = np.array([width])
    drive, out = np.zeros(1), np.zeros(1)
    for m in moves:
        new_drive = drive + m
        new_out = backlash(out, new_drive, w)
        assert abs(float(new_drive[0] - new_out[0])) <= width / 2 + 1e-12
        if abs(float(new_drive[0] - out[0])) <= width / 2:
            assert new_out[0] == out[0]  # inside the slack: the output does not move
        drive, out = new_drive, new_out


@given(st.floats(-200, 200), st.floats(-200, 200), st.floats(0.0, 50.0))
def test_move_toward_never_overshoots(x: float, target: float, rate: float) -> None:
    new, _ = move_toward(np.array([x]), np.array([target]), np.array([rate]), 0.02)
    assert min(x, target) - 1e-12 <= float(new[0]) <= max(x, target) + 1e-12
    assert abs(float(new[0]) - x) <= rate * 0.02 + 1e-12


@given(st.floats(-720, 720))
def test_stretch_violation_is_periodic_and_bounded(q3: float) -> None:
    q = np.array([0.0, 0.0, q3, 0.0, 0.0, 0.0])
    v = stretch_violation(q, 3.0)
    assert 0.0 <= v <= 3.0
    assert math.isclose(v, stretch_violation(q + np.array([0, 0, 360, 0, 0, 0]), 3.0), abs_tol=1e-9)


def test_area_violation_examples() -> None:
    assert area_violation(np.array([300.0, 0.0, 0.0]), -350.0, 90.0) == 0.0
    assert area_violation(np.array([300.0, 0.0, -400.0]), -350.0, 90.0) == 50.0
    assert area_violation(np.array([30.0, 40.0, 0.0]), -350.0, 90.0) == 40.0


commands = st.lists(
    st.tuples(*([st.integers(-12, 12)] * 6), st.integers(-20, 20)), min_size=1, max_size=12
)


@settings(max_examples=25)
@given(commands)
def test_any_command_sequence_keeps_limits_and_a_sane_report(
    seq: list[tuple[int, int, int, int, int, int, int]],
) -> None:
    core = SimCore(SimConfig(start_pose="unfolded", seed=5))
    pc = ScriptedPc(core)
    pc.enter_joint_mode()
    lo, hi = np.degrees(core.config.arm.lower_array), np.degrees(core.config.arm.upper_array)
    for *axes, grip in seq:
        cmd = MoveCommand(FrameId.JOINT, 0, tuple(axes), grip)  # type: ignore[arg-type]
        pc.run_cycles(2, move_frame(cmd, strict=False))
        q_true = np.degrees(core.truth().q_true)
        q_rep = np.degrees(core.truth().q_reported)
        assert np.all(np.isfinite(q_true))
        assert np.all(q_rep >= lo - 1e-6) and np.all(q_rep <= hi + 1e-6)
        # Reported vs true: backlash half-band + quantisation (+ joint 1's 0.3 % scale).
        err = np.abs(q_true - q_rep)
        bound = np.array([0.075, 0.025, 0.05, 0.15, 0.15, 0.15]) + 0.1
        bound[0] += 0.003 * abs(q_true[0])
        assert np.all(err <= bound + 1e-9)
        assert 0.0 <= core.truth().gripper <= 0.090
    for f in pc.frames:
        assert f.id in (FrameId.STATUS, FrameId.POSITION, FrameId.SYNC)
        if f.id == FrameId.STATUS:
            assert decode_status(f.data).mode in (0, 4)
