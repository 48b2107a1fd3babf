"""The jog's pure parts: command checks and scaling, slow-down zones, the reference law.

Scenarios with the simulator (judged on its truth) are in tests/test_jog_lockstep.py.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import jsonschema
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from manus.config import FOLDED_Q_DEG, UNFOLDED_Q_DEG, is_folded
from manus.errors import ConfigError, SchemaError
from manus.kinematics import fk
from manus.orientation import matrix_to_ypr
from manus.scene import Scene
from schemas.collision import ClearanceReport
from schemas.commands import JointVelocityCommand
from schemas.control import Refusal
from schemas.jog import JogCommand, JogLevel, JogState, LimitKind
from schemas.state import JointState
from services.controller.command_source import Refused, Sent
from services.controller.config import ControllerConfig
from services.controller.jog import JogSource
from services.controller.jog_command import JogError, resolve
from services.controller.jog_config import JogConfig
from services.controller.jog_law import JogRun, JogTarget, rodrigues
from services.controller.jog_limits import measures, slowdown
from services.controller.outbox import GoalOutcome

CFG = JogConfig()
CONFIG = ControllerConfig()
UNFOLDED = [math.radians(v) for v in UNFOLDED_Q_DEG]


def cmd(**kw: Any) -> JogCommand:
    base: dict[str, Any] = {"stamp_ns": 0, "seq": 1, "source": "test", "kind": "twist"}
    base["units"] = "si"
    base.update(kw)
    return JogCommand(**base)


# -- the command -----------------------------------------------------------------------------


def test_messages_round_trip_and_have_schemas() -> None:
    c = cmd(linear=[0.1, 0.0, 0.0], frame="gripper", drink=True, angular=[0.0, 0.0, 0.2])
    assert JogCommand.decode(c.encode()) == c
    assert JogLevel.decode(JogLevel(level=2).encode()).level == 2
    schema = JogCommand.json_schema()
    assert schema["properties"]["frame"]["enum"] == ["base", "gripper"]
    assert JogState.json_schema()["title"] == "JogState"


@pytest.mark.parametrize(
    ("payload", "field"),
    [
        ({"frame": "tool"}, "frame"),
        ({"kind": "dance"}, "kind"),
        ({"linear": [float("nan"), 0.0, 0.0]}, "linear"),
        ({"joints": [0.0] * 5}, "joints"),
    ],
)
def test_bad_payloads_do_not_decode(payload: dict[str, Any], field: str) -> None:
    data = cmd().to_dict() | payload
    with pytest.raises(SchemaError, match=field):
        JogCommand.from_dict(data)


def test_unitless_is_scaled_by_the_level_and_si_is_limited_by_it() -> None:
    t = resolve(cmd(units="unitless", linear=[1.0, 0.0, 0.0]), 5, CFG)
    assert t is not None and t.linear[0] == pytest.approx(0.150)
    t = resolve(cmd(units="unitless", linear=[0.5, 0.0, 0.0]), 2, CFG)
    assert t is not None and t.linear[0] == pytest.approx(0.5 * 0.150 * 2 / 5)
    # SI: within the level's cap as asked, above it scaled down (direction kept)
    t = resolve(cmd(linear=[0.03, 0.0, 0.0]), 1, CFG)
    assert t is not None and t.linear[0] == pytest.approx(0.03)
    t = resolve(cmd(linear=[0.09, 0.12, 0.0], angular=[0.0, 0.0, 0.1]), 1, CFG)
    assert t is not None
    assert math.hypot(*t.linear) == pytest.approx(0.03)
    assert t.linear[1] / t.linear[0] == pytest.approx(0.12 / 0.09)
    assert t.angular[2] / t.linear[0] == pytest.approx(0.1 / 0.09)
    j = resolve(cmd(kind="joints", units="unitless", joints=[1.0, 0, 0, 0, 0, -0.5]), 5, CFG)
    assert j is not None and j.joints[0] == pytest.approx(math.radians(50.0))
    assert j.joints[5] == pytest.approx(-math.radians(25.0))


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"linear": [0.2, 0.0, 0.0]}, r"`linear` speed 200.0 mm/s is above the cap 150.0 mm/s"),
        ({"units": "unitless", "linear": [1.5, 0.0, 0.0]}, r"`linear\[0\]` = 1.5 is outside"),
        ({"linear": [math.inf, 0.0, 0.0]}, r"`linear\[0\]` = inf is not a finite number"),
        ({"kind": "joints", "linear": [0.1, 0.0, 0.0]}, r"a `joints` command carries no `linear`"),
        ({"joints": [0.1, 0, 0, 0, 0, 0]}, r"a `twist` command carries no `joints`"),
        ({"kind": "joints", "drink": True}, r"a `joints` command carries no `drink`"),
        ({"drink": True, "angular": [0.1, 0.0, 0.0]}, "drink mode holds the cup level"),
        ({"pour": 0.1}, "needs drink mode"),
        ({"kind": "joints", "joints": [1.0, 0, 0, 0, 0, 0]}, "above the cap 50.0 deg/s"),
    ],
)
def test_bad_commands_are_refused_with_the_field_value_and_limit(
    kw: dict[str, Any], message: str
) -> None:
    with pytest.raises(JogError, match=message):
        resolve(cmd(**kw), 3, CFG)


def test_a_command_above_the_level_cap_is_scaled_and_says_so() -> None:
    # level 3 of 5: 90 mm/s; a 120 mm/s SI twist is held to 90 mm/s, and the target
    # carries the cap that did it (the jog state reports it: never silently)
    t = resolve(cmd(linear=[0.0, 0.12, 0.0]), 3, CFG)
    assert t is not None and t.linear[1] == pytest.approx(0.09)
    [cap] = t.caps
    assert (cap.kind, cap.object) == (LimitKind.SPEED_CAP, "linear")
    assert cap.scale == pytest.approx(0.75)
    within = resolve(cmd(linear=[0.0, 0.08, 0.0]), 3, CFG)
    assert within is not None and within.caps == ()
    g = resolve(cmd(gripper=0.03), 1, CFG)  # 6 mm/s at level 1: the gripper alone
    assert g is not None and g.gripper == pytest.approx(0.006)
    [grip] = g.caps
    assert grip.object == "gripper" and grip.scale == pytest.approx(0.2)
    full = resolve(cmd(units="unitless", linear=[1.0, 0.0, 0.0]), 5, CFG)
    assert full is not None and full.caps == ()  # a full deflection is the cap, not above


@pytest.mark.parametrize(
    ("fields", "valid"),
    [
        ({"kind": "twist", "linear": [0.1, 0.0, 0.0]}, True),
        ({"kind": "twist", "joints": [0.1, 0, 0, 0, 0, 0]}, False),
        ({"kind": "joints", "joints": [0.1, 0, 0, 0, 0, 0], "gripper": 0.01}, True),
        ({"kind": "joints", "linear": [0.1, 0.0, 0.0]}, False),
        ({"kind": "joints", "drink": True}, False),
        ({"kind": "stop", "linear": [0.1, 0.0, 0.0]}, True),
        ({"kind": "twist", "units": "unitless", "linear": [1.5, 0.0, 0.0]}, False),
        ({"kind": "twist", "drink": True, "angular": [0.1, 0.0, 0.0]}, False),
        ({"kind": "twist", "drink": True, "angular": [0.0, 0.0, 0.1], "pour": 0.1}, True),
        ({"kind": "twist", "pour": 0.1}, False),
    ],
)
def test_the_json_schema_says_what_each_kind_needs_as_the_controller_checks_it(
    fields: dict[str, Any], valid: bool
) -> None:
    """The exported schema and the controller's checks come from one table
    (``schemas.jog.KIND_FIELDS``): a client validating against the schema is refused for
    nothing the schema allows (SI caps aside: they are the controller's settings)."""
    payload = {"stamp_ns": 0, "seq": 1, "source": "t", "units": "si"} | fields
    schema = jsonschema.Draft202012Validator(JogCommand.json_schema())
    assert schema.is_valid(payload) == valid, list(schema.iter_errors(payload))
    try:
        resolve(JogCommand.from_dict(payload), 5, CFG)
    except JogError:
        assert not valid
    else:
        assert valid


def test_zero_and_stop_commands_mean_stop() -> None:
    assert resolve(cmd(), 3, CFG) is None
    assert resolve(cmd(kind="stop", linear=[0.1, 0.0, 0.0]), 3, CFG) is None
    grip = resolve(cmd(gripper=0.01), 3, CFG)
    assert grip is not None and not grip.arm_moves and grip.gripper == pytest.approx(0.01)


@given(
    st.lists(st.floats(-1.0, 1.0), min_size=7, max_size=7),
    st.integers(1, 5),
)
def test_scaled_speeds_never_exceed_the_level_caps(values: list[float], level: int) -> None:
    t = resolve(cmd(units="unitless", linear=values[:3], angular=values[3:6], gripper=values[6]),
                level, CFG)  # fmt: skip
    if t is None:
        return
    share = level / 5
    assert math.hypot(*t.linear) <= CFG.max_linear * share * (1 + 1e-9)
    assert math.hypot(*t.angular) <= CFG.max_angular * share * (1 + 1e-9)
    assert abs(t.gripper) <= CFG.max_gripper * share * (1 + 1e-9)


def test_config_is_checked() -> None:
    with pytest.raises(ConfigError, match="max_linear"):
        JogConfig(max_linear=0.3)
    with pytest.raises(ConfigError, match="max_joint"):
        JogConfig(max_joint=math.radians(60.0))
    with pytest.raises(ConfigError, match="default_level"):
        JogConfig(default_level=6)
    with pytest.raises(ConfigError, match="wrist_slow_deg"):
        JogConfig(wrist_slow_deg=4.0)


# -- the intake: deadman, latching, levels -----------------------------------------------------


class Host:
    """What the jog asks of the controller core, set by the test: the newest joint state
    (its stamp) and why nothing may move (None: it may)."""

    def __init__(self) -> None:
        self.config = CONFIG
        self.last_js: JointState | None = None
        self.not_ready: str | None = None

    def at(self, stamp_ns: int | None, not_ready: str | None = None) -> Host:
        """The newest joint state stamped ``stamp_ns`` (None: none yet)."""
        self.not_ready = not_ready
        if stamp_ns is None:
            self.last_js = None
            return self
        self.last_js = JointState(
            stamp_ns=stamp_ns, seq=0, position=list(UNFOLDED), gripper=0.0, valid=True,
            mode="joint", encoder=[0] * 7, applied_velocity=[0.0] * 6,
            applied_gripper_velocity=0.0, applied_kind="none", applied_seq=-1,
        )  # fmt: skip
        return self

    def admission(self, source: object) -> Refused | None:
        return None if self.not_ready is None else Refused(Refusal.NOT_READY, self.not_ready)

    def finish(self, outcome: GoalOutcome) -> None:
        raise AssertionError(f"the jog ends no goal: {outcome}")

    def clearance(self, goal_id: str) -> ClearanceReport | None:
        return None

    @property
    def scene(self) -> Scene | None:
        return None

    def move_object(self, name: str, pose: np.ndarray) -> None:
        raise AssertionError(f"the jog moves no object: {name}")


def moving(jog: JogSource) -> bool:
    """``jog.engaged``, read afresh (no narrowing across calls)."""
    return jog.engaged


def test_refusal_and_stops_latch_until_a_zero_command() -> None:
    host = Host()
    jog = JogSource(host)
    host.at(1_000)
    jog.on_command(cmd(linear=[0.05, 0.0, 0.0]))
    assert moving(jog)
    jog.on_command(cmd(linear=[0.5, 0.0, 0.0]))  # above the cap
    assert not moving(jog) and jog.refused == 1
    assert "above the cap" in jog.reason and "release the controls" in jog.reason
    jog.on_command(cmd(linear=[0.05, 0.0, 0.0]))  # still held
    assert not moving(jog)
    jog.on_command(cmd())  # released
    jog.on_command(cmd(linear=[0.05, 0.0, 0.0]))
    assert moving(jog)
    host.at(None)
    jog.on_command(cmd(linear=[0.05, 0.0, 0.0]))
    assert not moving(jog) and "no valid joint state" in jog.reason
    stopped = "the bridge is in phase 'stopped'"
    host.at(2_000, stopped)
    jog.on_command(cmd())  # a release is always taken
    assert jog.refused == 2 and jog.stopped is None
    jog.on_command(cmd(linear=[0.05, 0.0, 0.0]))
    jog.on_command(cmd(linear=[0.05, 0.0, 0.0]))  # held: one refusal
    assert jog.refused == 3 and not moving(jog) and stopped in jog.reason


def test_the_state_says_whether_the_arm_is_folded() -> None:
    host = Host()
    jog = JogSource(host)
    host.at(1_000)
    assert jog.set_level(JogLevel(level=2)).accepted  # a change to show
    js = host.last_js
    assert js is not None
    folded = dataclasses.replace(js, position=[math.radians(v) for v in FOLDED_Q_DEG])
    for state, expected in ((js, False), (folded, True)):
        jog.announce = True
        out = jog.reports(Sent(state, JointVelocityCommand(
            stamp_ns=0, seq=0, source="c", ref_seq=0, velocity=[0.0] * 6, gripper_velocity=0.0
        ), ""))  # fmt: skip
        [(_, msg)] = out
        assert isinstance(msg, JogState) and msg.folded is expected
        assert msg.state == "idle" and msg.caps.linear == pytest.approx(CFG.max_linear * 2 / 5)
    assert is_folded([math.radians(v + 4.0) for v in FOLDED_Q_DEG])
    assert not is_folded([math.radians(v + 6.0) for v in FOLDED_Q_DEG])


def test_levels() -> None:
    jog = JogSource(Host())
    assert jog.level == 3
    assert jog.set_level(JogLevel(level=5)).accepted and jog.level == 5
    assert jog.set_level(JogLevel(level=6)).reason == "level 6 outside 1..5"
    assert jog.level == 5


# -- slow-down ---------------------------------------------------------------------------------


def test_measures() -> None:
    q = [0.0, 0.0, math.radians(80.0), 0.0, math.radians(-175.0), 0.0]
    m = {(kind, name): deg for kind, name, deg in measures(q, CONFIG.arm)}
    assert m[LimitKind.SINGULARITY, "wrist"] == pytest.approx(5.0)
    assert m[LimitKind.SINGULARITY, "elbow"] == pytest.approx(10.0)
    assert m[LimitKind.JOINT_LIMIT, "joint 5"] == pytest.approx(-55.0)  # beyond -120 deg
    assert m[LimitKind.JOINT_LIMIT, "joint 3"] == pytest.approx(360.0 - 80.0)


def test_slowdown_toward_a_zone_never_away_and_never_past_the_stop() -> None:
    arm = CONFIG.arm
    q0 = [0.0, 0.0, 0.0, 0.0, math.radians(12.0), 0.0]
    toward = [0.0, 0.0, 0.0, 0.0, math.radians(11.0), 0.0]
    away = [0.0, 0.0, 0.0, 0.0, math.radians(13.0), 0.0]
    s = slowdown(q0, toward, arm, CFG)
    assert s.scale == pytest.approx((12.0 - 5.0) / (20.0 - 5.0))
    assert (s.kind, s.object) == (LimitKind.SINGULARITY, "wrist")
    assert s.angle == pytest.approx(math.radians(12.0))
    assert s.words.startswith("the wrist singularity (q5 near 0 or 180 deg)")
    assert slowdown(q0, away, arm, CFG).scale == 1.0
    jump = [0.0, 0.0, 0.0, 0.0, math.radians(-3.0), 0.0]  # across the singularity
    s = slowdown(q0, jump, arm, CFG)
    assert s.scale * 15.0 <= 12.0 - 5.0 + 1e-9  # stops at 5 deg, never flips
    at_stop = [0.0, 0.0, 0.0, 0.0, math.radians(5.0), 0.0]
    s = slowdown(at_stop, [0.0, 0.0, 0.0, 0.0, math.radians(4.0), 0.0], arm, CFG)
    assert s.scale == 0.0 and s.object == "wrist"


# -- the reference ---------------------------------------------------------------------------


def test_rodrigues_is_a_rotation_about_its_axis() -> None:
    R = rodrigues(np.array([0.0, 0.0, math.pi / 2]))
    assert R @ np.array([1.0, 0.0, 0.0]) == pytest.approx(np.array([0.0, 1.0, 0.0]))
    assert rodrigues(np.zeros(3)) == pytest.approx(np.eye(3))


def _drive(target: JogTarget, cycles: int, q: list[float] | None = None) -> list[np.ndarray]:
    """Poses of the reference over ``cycles`` cycles, the arm following it exactly."""
    q = list(q or UNFOLDED)
    run = JogRun.start(target, q, CONFIG)
    poses = [fk(q, CONFIG.arm)]
    for _ in range(cycles):
        q = run.step(target, q, CFG, CONFIG).q_target
        poses.append(fk(q, CONFIG.arm))
    return poses


def _twist(**kw: Any) -> JogTarget:
    base: dict[str, Any] = {"kind": "twist", "frame": "base", "linear": (0.0,) * 3,
                            "angular": (0.0,) * 3, "joints": (0.0,) * 6, "gripper": 0.0,
                            "drink": False, "pour": 0.0}  # fmt: skip
    base.update(kw)
    return JogTarget(**base)


def test_a_pure_x_twist_moves_the_reference_in_a_straight_line_with_a_ramp() -> None:
    poses = _drive(_twist(linear=(0.15, 0.0, 0.0)), 12)
    p = np.array([T[:3, 3] for T in poses]) - poses[0][:3, 3]
    assert np.abs(p[:, 1:]).max() < 1e-6  # straight: no y, z (m)
    steps = np.diff(p[:, 0])
    assert steps[0] == pytest.approx(CFG.linear_accel * 0.06 * 0.06, abs=1e-7)  # the ramp
    assert steps[-1] == pytest.approx(0.15 * 0.06, abs=1e-7)  # then the commanded speed
    R0, R1 = poses[0][:3, :3], poses[-1][:3, :3]
    assert np.abs(R0 - R1).max() < 1e-6  # orientation kept


def test_gripper_frame_twist_moves_along_the_gripper_axes() -> None:
    poses = _drive(_twist(frame="gripper", linear=(0.0, 0.0, 0.05)), 10)
    moved = poses[-1][:3, 3] - poses[0][:3, 3]
    approach = poses[0][:3, 2]
    assert np.dot(moved, approach) == pytest.approx(np.linalg.norm(moved), rel=1e-5)


def test_drink_mode_keeps_pitch_and_roll_and_pours_about_the_rim() -> None:
    poses = _drive(_twist(drink=True, linear=(0.05, 0.03, 0.0), angular=(0.0, 0.0, 0.2)), 15)
    y0, p0, r0 = matrix_to_ypr(poses[0][:3, :3])
    y1, p1, r1 = matrix_to_ypr(poses[-1][:3, :3])
    assert (p1, r1) == pytest.approx((p0, r0), abs=1e-6)
    assert y1 - y0 > 0.1
    # pour: the rim point stays where it is while the cup tilts
    pour = _drive(_twist(drink=True, pour=0.3), 10)
    rim = np.asarray(CFG.rim_offset)
    rims = [T[:3, :3] @ rim + T[:3, 3] for T in pour]
    assert np.abs(np.array(rims) - rims[0]).max() < 1e-6
    tilt = math.degrees(math.acos(np.clip(pour[0][:3, 1] @ pour[-1][:3, 1], -1, 1)))
    assert tilt < 1e-3  # about the gripper's own y axis
    assert np.abs(pour[0][:3, :3] - pour[-1][:3, :3]).max() > 0.05


def test_the_reference_stops_before_the_wrist_singularity_never_flipping() -> None:
    q = list(UNFOLDED)
    q[4] = math.radians(-25.0)
    target = JogTarget("joints", "base", (0.0,) * 3, (0.0,) * 3,
                       (0.0, 0.0, 0.0, 0.0, math.radians(30.0), 0.0), 0.0, False, 0.0)  # fmt: skip
    run = JogRun.start(target, q, CONFIG)
    seen = []
    for _ in range(60):
        step = run.step(target, q, CFG, CONFIG)
        q = step.q_target
        seen.append(math.degrees(q[4]))
    assert max(seen) < -CFG.wrist_stop_deg + 1e-9  # stopped before, still on its side
    assert seen[-1] > -CFG.wrist_stop_deg - 0.5  # and came close
    assert step.limit.scale < 1.0 and step.limit.kind == LimitKind.SINGULARITY


def test_the_joint_cap_scales_the_whole_step() -> None:
    fast = JogConfig(max_angular=math.radians(90.0))  # the wrist cannot turn that fast
    target = _twist(linear=(0.0, 0.0, 0.1), angular=(math.radians(80.0), 0.0, 0.0))
    q = list(UNFOLDED)
    run = JogRun.start(target, q, CONFIG)
    capped = 0
    for _ in range(20):
        step = run.step(target, q, fast, CONFIG)
        capped += (step.limit.kind, step.limit.object) == (LimitKind.SPEED_CAP, "motors")
        dq = np.subtract(step.q_target, q)
        motors = np.abs([dq[0], -dq[1], dq[2] - dq[1], dq[3], dq[4], dq[5]])
        assert motors.max() <= math.radians(50.0) * 0.06 + 1e-6
        q = step.q_target
    assert capped > 5


def test_the_reference_restarts_when_the_arm_is_held_back() -> None:
    target = _twist(linear=(0.1, 0.0, 0.0))
    q = list(UNFOLDED)
    run = JogRun.start(target, q, CONFIG)
    for _ in range(5):
        step = run.step(target, q, CFG, CONFIG)  # the arm does not move at all
    assert step.reanchored  # from where the arm is, one cycle ahead: no runaway
    assert np.abs(np.subtract(step.q_target, q)).max() < math.radians(50.0) * 0.06 + 1e-9
