"""The planner core: thesis paths, exact knots, refusals that name where, speed limits."""

from __future__ import annotations

import math
from pathlib import Path as FilePath

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from manus.config import DEFAULT_ARM, DEG, UNFOLDED_Q_DEG, ArmConfig
from manus.kinematics import fk, jacobian
from manus.orientation import matrix_to_ypr
from manus.trajectory import JointTrajectory
from manus.viapoints import load_path, parse_viapoints
from schemas.planning import PlanReply, PlanRequest, Trajectory, ViaPointPath
from schemas.state import JointState
from services.planner.config import PlannerConfig
from services.planner.core import PlannerCore
from services.planner.spline import PiecewisePolynomial

ROOT = FilePath(__file__).resolve().parent.parent
UNFOLDED = np.radians(UNFOLDED_Q_DEG)
START = "0 0 0 0 0 0 0 0 0 0 0 0 0 0"


def plan_text(
    text: str,
    start: np.ndarray = UNFOLDED,
    core: PlannerCore | None = None,
    **options: object,
) -> PlanReply:
    preview_dt = float(options.pop("preview_dt", 0.06))  # type: ignore[arg-type]
    motion = ViaPointPath(path=parse_viapoints(text, "test.txt"), **options)  # type: ignore[arg-type]
    request = PlanRequest(motion, start=list(start), preview_dt=preview_dt)
    return (core or PlannerCore()).plan(request)


def pose_line(q_deg: tuple[float, ...], time: float) -> str:
    """An absolute (type 0) via point at the gripper pose of ``q_deg``."""
    T = fk(np.radians(q_deg), DEFAULT_ARM)
    yaw, pitch, roll = (float(a) for a in np.degrees(matrix_to_ypr(T[:3, :3])))
    x, y, z = (float(c) for c in T[:3, 3] * 1000.0)
    return f"{x!r} {y!r} {z!r} 0 0 0 {yaw!r} {roll!r} {pitch!r} 0 0 0 {time} 0"


def expected_xyz(path_file: str) -> np.ndarray:
    """Via points of a thesis file resolved by hand: start position + running offsets."""
    path = load_path(ROOT / "paths" / path_file)
    p = fk(UNFOLDED, DEFAULT_ARM)[:3, 3]
    out = [p]
    for vp in path.via_points[1:]:
        assert vp.type == 2
        out.append(out[-1] + np.array(vp.xyz))
    return np.array(out)


def ok(reply: PlanReply) -> Trajectory:
    assert reply.ok, reply.error
    assert reply.trajectory is not None
    return reply.trajectory


@pytest.mark.parametrize("name", ["thesis_square.txt", "thesis_circle.txt"])
@pytest.mark.parametrize("interpolation", ["cubic", "quintic"])
def test_thesis_paths_plan_from_the_unfolded_pose(name: str, interpolation: str) -> None:
    path = load_path(ROOT / "paths" / name)
    reply = PlannerCore().plan(
        PlanRequest(ViaPointPath(path=path, interpolation=interpolation), start=list(UNFOLDED))
    )
    traj = ok(reply)
    assert reply.start == pytest.approx(list(UNFOLDED))
    assert traj.times == [vp.time for vp in path.via_points]
    assert traj.via_lines == [vp.line for vp in path.via_points]
    assert traj.time_scale == 1.0
    q = np.array(traj.positions)
    assert q[0] == pytest.approx(UNFOLDED, abs=0)
    # Every knot's FK is its via point, to 1e-6 mm, with the start's orientation kept.
    want = expected_xyz(name)
    poses = np.array([fk(row, DEFAULT_ARM) for row in q])
    assert np.abs(poses[:, :3, 3] - want).max() < 1e-9
    assert np.abs(poses[:, :3, :3] - fk(UNFOLDED, DEFAULT_ARM)[:3, :3]).max() < 1e-9
    assert np.abs(np.array(traj.via_xyz) - want).max() < 1e-9
    assert bool(traj.accelerations) == (interpolation == "quintic")
    JointTrajectory(traj)  # a valid message for the controller


def test_cubic_equals_scipy_on_the_planned_knots() -> None:
    traj = ok(plan_text((ROOT / "paths" / "thesis_circle.txt").read_text()))
    t, q = np.array(traj.times), np.array(traj.positions)
    reference = CubicSpline(t, q, bc_type=((1, np.zeros(6)), (1, np.zeros(6))))
    assert np.abs(np.array(traj.velocities) - reference(t, 1)).max() < 1e-9
    ts = np.linspace(0.0, t[-1] - 1e-9, 1500)
    q_s, qd_s, _ = JointTrajectory(traj).sample_many(ts)
    assert np.abs(q_s - reference(ts)).max() < 1e-9
    assert np.abs(qd_s - reference(ts, 1)).max() < 1e-9


def test_quintic_starts_and_stops_without_acceleration() -> None:
    traj = ok(
        plan_text((ROOT / "paths" / "thesis_square.txt").read_text(), interpolation="quintic")
    )
    a = np.array(traj.accelerations)
    assert np.all(a[0] == 0.0) and np.all(a[-1] == 0.0)
    assert np.all(np.array(traj.velocities)[[0, -1]] == 0.0)
    assert any("quintic" in note for note in traj.notes)


def test_preview_samples_the_gripper_every_60_ms() -> None:
    traj = ok(plan_text((ROOT / "paths" / "thesis_square.txt").read_text()))
    preview = np.array(traj.preview_xyz)
    assert traj.preview_dt == pytest.approx(0.06)
    assert len(preview) == 321  # 0 .. 19.2 s
    assert preview[0] == pytest.approx(traj.via_xyz[0], abs=1e-12)
    assert preview[-1] == pytest.approx(traj.via_xyz[-1], abs=1e-12)
    # The gripper stays near the square's plane (x constant) between the via points.
    assert np.abs(preview[:, 0] - preview[0, 0]).max() < 0.01
    none = ok(plan_text((ROOT / "paths" / "thesis_square.txt").read_text(), preview_dt=0.0))
    assert none.preview_xyz == [] and none.preview_dt == 0.0


def test_relative_types_resolve_against_first_and_previous() -> None:
    text = "\n".join(
        [START, "0 10 0 0 0 0 0 0 0 0 0 0 1 2", "0 10 0 0 0 0 0 0 0 0 0 0 2 2",
         "0 0 30 0 0 0 0 0 0 0 0 0 3 1", "250 100 250 0 0 0 0 0 -60 0 0 0 4 0"]
    )  # fmt: skip
    traj = ok(plan_text(text))
    p0 = fk(UNFOLDED, DEFAULT_ARM)[:3, 3]
    offsets = np.array([[0, 0, 0], [0, 0.01, 0], [0, 0.02, 0], [0, 0, 0.03]])
    want = np.vstack([p0 + offsets, [0.25, 0.1, 0.25]])
    assert np.abs(np.array(traj.via_xyz) - want).max() < 1e-9
    R_last = fk(np.array(traj.positions[-1]), DEFAULT_ARM)[:3, :3]
    assert np.degrees(matrix_to_ypr(R_last)) == pytest.approx([0.0, -60.0, 0.0], abs=1e-7)


def test_angles_add_in_yaw_pitch_roll() -> None:
    # File order yaw ROLL pitch: +10 deg of roll, then +5 deg of yaw.
    text = f"{START}\n0 0 0 0 0 0 0 10 0 0 0 0 1 2\n0 0 0 0 0 0 5 0 0 0 0 0 2 2\n"
    traj = ok(plan_text(text))
    ypr = [np.degrees(matrix_to_ypr(fk(np.array(q), DEFAULT_ARM)[:3, :3])) for q in traj.positions]
    assert ypr[1] == pytest.approx([0.0, -60.0, 10.0], abs=1e-7)
    assert ypr[2] == pytest.approx([5.0, -60.0, 10.0], abs=1e-7)


def test_boundary_velocities_go_through_the_jacobian() -> None:
    # Last via point moving at 20 mm/s along y and turning at 3 deg/s of yaw.
    text = f"{START}\n0 50 0 0 20 0 0 0 0 3 0 0 4 2\n"
    traj = ok(plan_text(text))
    q_last, v_last = np.array(traj.positions[-1]), np.array(traj.velocities[-1])
    twist = jacobian(q_last, DEFAULT_ARM) @ v_last
    assert twist[:3] == pytest.approx([0.0, 0.02, 0.0], abs=1e-12)
    assert twist[3:] == pytest.approx([0.0, 0.0, math.radians(3.0)], abs=1e-12)  # yaw is about z


def _refused(reply: PlanReply, reason: str) -> str:
    assert not reply.ok and reply.trajectory is None
    assert reply.error is not None, reply
    assert reply.error.reason == reason, reply.error
    assert "\n" not in reply.error.message
    return reply.error.message


def test_unreachable_via_point_is_refused_naming_its_line() -> None:
    text = f"# header\n{START}\n0 20 0 0 0 0 0 0 0 0 0 0 1 2\n2000 0 0 0 0 0 0 0 0 0 0 0 2 0\n"
    reply = plan_text(text)
    message = _refused(reply, "unreachable")
    assert reply.error is not None
    assert (reply.error.via_point, reply.error.line) == (2, 4)
    assert message.startswith("test.txt line 4 (via point 2): outside the workspace")
    assert "beyond the arm's reach" in message


def test_wrist_singular_via_point_is_refused() -> None:
    text = f"{START}\n{pose_line((0, 30, -30, 0, -0.5, 0), 3.0)}\n"
    reply = plan_text(text)
    message = _refused(reply, "singular")
    assert reply.error is not None
    assert (reply.error.via_point, reply.error.line, reply.error.joint) == (1, 2, 5)
    assert "joint 5 at -0.50 deg" in message


def test_joint_limit_at_a_via_point_is_refused() -> None:
    start = np.radians([0, 30, -30, 0, -110, 0])
    text = f"{START}\n{pose_line((0, 30, -30, 0, -125, 0), 3.0)}\n"
    reply = plan_text(text, start=start)
    message = _refused(reply, "joint_limit")
    assert reply.error is not None
    assert (reply.error.via_point, reply.error.joint) == (1, 5)
    assert reply.error.value == pytest.approx(math.radians(-125.0))
    assert reply.error.limit == pytest.approx(math.radians(-120.0))
    assert "joint 5 would be at -125.00 deg, beyond its limit -120.0 deg" in message


def test_start_beyond_a_limit_is_refused() -> None:
    reply = plan_text(
        f"{START}\n0 10 0 0 0 0 0 0 0 0 0 0 1 2\n", start=np.radians([0, 30, -30, 0, -125, 0])
    )
    assert "the start configuration: joint 5 at -125.00 deg" in _refused(reply, "joint_limit")


def test_branch_flip_is_refused() -> None:
    text = f"{START}\n{pose_line((120, 30, -30, 0, -60, 0), 10.0)}\n"
    reply = plan_text(text)
    message = _refused(reply, "branch")
    assert reply.error is not None
    assert (reply.error.via_point, reply.error.joint) == (1, 1)
    assert "joint 1 would jump 120.0 deg" in message and "branch flip" in message


def _check_curve(q5_deg: list[float], v5_deg: list[float]) -> PlanReply:
    """Run the trajectory checks on a hand-made two-knot curve of joint 5."""
    from services.planner.checks import check_geometry
    from services.planner.errors import PlanningError
    from services.planner.labels import KnotLabels

    q = np.tile(UNFOLDED, (2, 1))
    v = np.zeros((2, 6))
    q[:, 4], v[:, 4] = np.radians(q5_deg), np.radians(v5_deg)
    curve = PiecewisePolynomial.hermite(np.array([0.0, 1.0]), q, v)
    path = parse_viapoints(f"{START}\n0 0 0 0 0 0 0 0 0 0 0 0 1 2\n", "curve.txt")
    try:
        check_geometry(curve, KnotLabels.of_path(path), (1, -1, -1), PlannerConfig())
    except PlanningError as exc:
        return PlanReply(ok=False, error=exc.error)
    return PlanReply(ok=True)


def test_wrist_singularity_between_knots_is_caught() -> None:
    # Both knots at q5 = -10 deg, but the cubic bulges through 0 in between.
    message = _refused(_check_curve([-10.0, -10.0], [40.0, -40.0]), "singular")
    assert "between curve.txt line 1 (via point 0) and line 2 (via point 1)" in message
    assert "t = 0.500 s" in message
    assert _check_curve([-10.0, -10.0], [10.0, -10.0]).ok


def test_joint_limit_between_knots_is_caught() -> None:
    message = _refused(_check_curve([-115.0, -115.0], [-40.0, 40.0]), "joint_limit")
    assert "joint 5 reaches -125.00 deg at t = 0.500 s, beyond its limit -120.0 deg" in message


def test_speed_limit_is_refused_naming_joint_time_and_limit() -> None:
    text = f"{START}\n0 300 0 0 0 0 0 0 0 0 0 0 0.5 2\n"
    reply = plan_text(text)
    message = _refused(reply, "speed_limit")
    assert reply.error is not None and reply.error.limit == pytest.approx(50 * DEG)
    assert reply.error.value is not None and reply.error.value > 50 * DEG
    assert f"joint {reply.error.joint} speed" in message
    assert "at t = " in message and "above its limit 50.0 deg/s" in message
    assert "ask for speed scaling" in message


def test_speed_scaling_stretches_time_just_enough() -> None:
    text = f"{START}\n0 200 0 0 0 0 0 0 0 0 0 0 1 2\n0 0 -100 0 0 0 0 0 0 0 0 0 1.5 2\n"
    traj = ok(plan_text(text, speed_scaling=True))
    k = traj.time_scale
    assert k > 1.0
    assert traj.times == pytest.approx([0.0, k, 1.5 * k])
    assert any("time stretched" in note for note in traj.notes)
    ts = np.linspace(0.0, traj.times[-1], 20001)
    _, qd, qdd = JointTrajectory(traj).sample_many(ts)
    speed, accel = np.abs(qd).max() / (50 * DEG), np.abs(qdd).max() / (200 * DEG)
    assert speed <= 1.0 and accel <= 1.0
    assert max(speed, accel) == pytest.approx(1.0, rel=1e-3)  # the smallest stretch


def test_acceleration_limit_is_checked_too() -> None:
    arm = ArmConfig(max_accel=tuple(5 * DEG for _ in range(6)))
    core = PlannerCore(PlannerConfig(arm=arm))
    text = f"{START}\n0 60 0 0 0 0 0 0 0 0 0 0 2 2\n"
    assert "acceleration" in _refused(plan_text(text, core=core), "speed_limit")
    traj = ok(plan_text(text, core=core, speed_scaling=True))
    _, _, qdd = JointTrajectory(traj).sample_many(np.linspace(0, traj.times[-1], 5001))
    assert np.abs(qdd).max() <= 5 * DEG * (1 + 1e-9)


def test_singular_jacobian_with_a_boundary_velocity_is_refused() -> None:
    stretched = np.radians([0, 30, 90, 0, -60, 0])  # elbow straight
    text = "0 0 0 10 0 0 0 0 0 0 0 0 0 0\n-50 0 0 0 0 0 0 0 0 0 0 0 5 2\n"
    message = _refused(plan_text(text, start=stretched), "singular")
    assert "Jacobian there is singular" in message


def test_start_from_the_latest_valid_joint_state() -> None:
    core = PlannerCore()
    request = PlanRequest(
        ViaPointPath(path=parse_viapoints(f"{START}\n0 10 0 0 0 0 0 0 0 0 0 0 1 2\n"))
    )
    assert "no start configuration" in _refused(core.plan(request), "no_state")

    def state(q: np.ndarray, valid: bool, seq: int) -> JointState:
        return JointState(stamp_ns=seq, seq=seq, position=list(q), gripper=0.0, valid=valid,
                          mode="joint", encoder=[0] * 7, applied_velocity=[0.0] * 6,
                          applied_gripper_velocity=0.0,
                          applied_kind="none", applied_seq=-1)  # fmt: skip

    core.on_joint_state(state(np.zeros(6), valid=False, seq=1))
    assert core.latest is None
    core.on_joint_state(state(UNFOLDED, valid=True, seq=2))
    assert ok(core.plan(request)).positions[0] == pytest.approx(list(UNFOLDED))
    other = np.radians([10, 30, -30, 0, -60, 0])
    reply = core.plan(request, state(other, valid=True, seq=3))
    assert reply.start == pytest.approx(list(other))
    _refused(core.plan(request, state(other, valid=False, seq=4)), "no_state")


def test_inconsistent_requests_get_structured_errors() -> None:
    path = parse_viapoints(f"{START}\n0 10 0 0 0 0 0 0 0 0 0 0 1 2\n", "p.txt")
    late = path.via_points[1]
    swapped = type(path)(via_points=[path.via_points[0], late, late], source="p.txt")
    reply = PlannerCore().plan(PlanRequest(ViaPointPath(path=swapped), start=list(UNFOLDED)))
    message = _refused(reply, "parse")
    assert reply.error is not None and reply.error.line == 2 and reply.error.via_point == 2
    assert "p.txt:2: via point 2: column time = 1 s" in message
    bad_start = PlanRequest(ViaPointPath(path=path), start=[math.nan] * 6)
    _refused(PlannerCore().plan(bad_start), "invalid")


def test_same_request_same_reply() -> None:
    request = PlanRequest(
        ViaPointPath(path=load_path(ROOT / "paths" / "thesis_circle.txt")), start=list(UNFOLDED)
    )
    assert PlannerCore().plan(request).encode() == PlannerCore().plan(request).encode()


def test_reply_decoding_still_rejects_bad_rows() -> None:
    import msgpack

    from manus.errors import SchemaError

    traj = ok(plan_text(f"{START}\n0 10 0 0 0 0 0 0 0 0 0 0 1 2\n"))
    data = PlanReply(ok=True, trajectory=traj).to_dict()
    data["trajectory"]["positions"][1][2] = math.nan
    with pytest.raises(SchemaError, match=r"trajectory.positions\[1\]\[2\]: expected a finite"):
        PlanReply.decode(msgpack.packb(data))
    data["trajectory"]["positions"][1][2] = 1e308
    data["trajectory"]["positions"][1][3] = 1e308  # finite values whose sum overflows
    assert PlanReply.decode(msgpack.packb(data)).trajectory is not None
