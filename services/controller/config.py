"""Controller settings: one frozen, validated dataclass with units in every name or doc.

The timing constants describe the arm's cycle as the controller sees it
(docs/architecture.md, Time): a joint state's snapshot was taken ``snapshot_age_ms``
before its stamp, and the command computed from it acts on the arm from
``command_delay_ms`` after the snapshot, for one ``cycle_ms``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

from manus.config import DEFAULT_ARM, ArmConfig
from manus.errors import ConfigError
from services.controller.follow_config import FollowConfig
from services.controller.jog_config import JogConfig

MS = 1_000_000
"""One millisecond [ns]."""
QUANTIZERS = ("rounding", "error_feedback", "cartesian")
"""Quantizers of the default mode (:mod:`manus.quantize`)."""


def _check(name: str, value: float, lo: float, hi: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and lo <= value <= hi):
        raise ConfigError(f"`{name}` must be in [{lo:g}, {hi:g}], got {value!r}")


@dataclass(frozen=True)
class ControllerConfig:
    """How the controller tracks, settles, stops and judges goals.

    Attributes:
        arm: geometry (forward kinematics of the via-point errors) and speed limits.
        cycle_ms: the arm's cycle, also how long one command acts [ms].
        snapshot_age_ms: time from the arm's position snapshot to the joint state's
            stamp (0x350 at T+20, 0x360 received at T+40) [ms].
        command_delay_ms: time from the snapshot to the moment the command computed
            from it starts acting (sync at T+60, active at T+80) [ms].
        drive_tau_ms: time constant of the arm's speed transient, used by the default
            mode's prediction [ms].
        encoder_unit_deg: resolution of the reported motor angles [deg]; the default
            mode's estimate of the true motor angle stays within half of it of the
            reading.
        thesis_gain: K of the thesis law qdot = qdot_ref + K (q_ref - q) [1/s].
        thesis_via_threshold_m: thesis mode: a segment ends when the gripper is this
            close to its via point [m].
        settle_speed: thesis mode: the final re-plan runs its largest joint move at this
            mean speed [rad/s].
        settle_min_s: thesis mode: shortest final re-plan [s].
        max_settles: thesis mode: re-plans after the last via point before giving up.
        cancel_decel: deceleration of a cancel (largest joint, all joints scaled
            together) [rad/s^2].
        speed_scale_rate: fastest change of the run-time speed scale [1/s].
        splice_blend_s: a replacing trajectory absorbs the difference of position,
            velocity and acceleration at the splice over this time [s] (at most its
            own duration, at least one cycle).
        max_stamp_gap_ms: joint states further apart than this are a gap: answered
            with zeros, the trajectory's time waits [ms].
        max_outage_ms: a gap with more than this missing (stamps, or seq jumps times
            the cycle) aborts every goal [ms].
        gripper_gain: gripper loop: commanded opening speed per error, after the
            delay compensation [1/s].
        delay_compensation: default mode: predict the motor angles at the time the
            command acts (from the increments in flight) and aim one cycle later; off:
            aim from the reading as if the command acted at once (for comparison).
        observer: default mode: keep a sub-unit estimate of the motor angles inside the
            encoder's quantization cell; off: use the readings as they are.
        default_quantizer: default mode: ``rounding`` (the residual is fed back through
            the position prediction), ``error_feedback`` (sigma-delta on the rates) or
            ``cartesian`` (round each joint up or down so that the gripper lands nearest).
        rounding_rotation_m: weight of the gripper's orientation error against its
            position error in the ``cartesian`` rounding [m/rad].
        rounding_joint_m: weight of each joint's own deviation from its ideal count in
            the ``cartesian`` rounding [m/rad]; discourages trading one joint's rounding
            against another's (wrist chatter).
        backlash_deg: default mode: full dead band of each motor's belt, motors 1..6,
            as calibrated [deg]; the motor targets are moved so that the joint side,
            not the motor, follows the reference. Zeros (the default): off; the
            encoders cannot see the play, so with it on the encoder-based via errors
            grow by up to half a band while the true ones shrink.
        backlash_dead_zone_deg: an estimated belt output this close to its target is
            not pushed [deg].
        scene: what the collision guard keeps every command clear of (:mod:`.guard`;
            :func:`manus.scene.scene_from_setting`: ``""`` = ``$MANUS_SCENE`` or the
            shipped wheelchair scene, ``default``, ``none`` or a scene file).
        jog: live control (:class:`~services.controller.jog_config.JogConfig`).
        follow: following a target
            (:class:`~services.controller.follow_config.FollowConfig`).
    """

    arm: ArmConfig = field(default_factory=lambda: DEFAULT_ARM)
    cycle_ms: float = 60.0
    snapshot_age_ms: float = 20.0
    command_delay_ms: float = 60.0
    drive_tau_ms: float = 20.0
    encoder_unit_deg: float = 0.1
    thesis_gain: float = 2.5
    thesis_via_threshold_m: float = 0.003
    settle_speed: float = math.radians(5.0)
    settle_min_s: float = 0.12
    max_settles: int = 5
    cancel_decel: float = math.radians(100.0)
    speed_scale_rate: float = 2.0
    splice_blend_s: float = 1.0
    max_stamp_gap_ms: float = 90.0
    max_outage_ms: float = 300.0
    gripper_gain: float = 1.0 / 0.06
    delay_compensation: bool = True
    observer: bool = True
    default_quantizer: str = "cartesian"
    rounding_rotation_m: float = 0.05
    rounding_joint_m: float = 0.2
    backlash_deg: tuple[float, ...] = (0.0,) * 6
    backlash_dead_zone_deg: float = 0.02
    scene: str = ""
    jog: JogConfig = field(default_factory=JogConfig)
    follow: FollowConfig = field(default_factory=FollowConfig)

    def __post_init__(self) -> None:
        _check("cycle_ms", self.cycle_ms, 1.0, 1000.0)
        _check("snapshot_age_ms", self.snapshot_age_ms, 0.0, 1000.0)
        _check("command_delay_ms", self.command_delay_ms, 0.0, 1000.0)
        _check("drive_tau_ms", self.drive_tau_ms, 0.0, 1000.0)
        _check("encoder_unit_deg", self.encoder_unit_deg, 0.0, 10.0)
        _check("thesis_gain", self.thesis_gain, 0.0, 100.0)
        _check("thesis_via_threshold_m", self.thesis_via_threshold_m, 0.0, 1.0)
        _check("settle_speed", self.settle_speed, 1e-3, math.radians(50.0))
        _check("settle_min_s", self.settle_min_s, 0.0, 60.0)
        _check("max_settles", self.max_settles, 0, 100)
        _check("cancel_decel", self.cancel_decel, 1e-3, 1e4)
        _check("speed_scale_rate", self.speed_scale_rate, 1e-3, 1e3)
        _check("splice_blend_s", self.splice_blend_s, 0.0, 60.0)
        _check("max_stamp_gap_ms", self.max_stamp_gap_ms, self.cycle_ms, 10_000.0)
        _check("max_outage_ms", self.max_outage_ms, 0.0, 60_000.0)
        _check("gripper_gain", self.gripper_gain, 0.0, 1000.0)
        _check("rounding_rotation_m", self.rounding_rotation_m, 0.0, 10.0)
        _check("rounding_joint_m", self.rounding_joint_m, 0.0, 10.0)
        _check("backlash_dead_zone_deg", self.backlash_dead_zone_deg, 0.0, 10.0)
        object.__setattr__(self, "backlash_deg", tuple(float(v) for v in self.backlash_deg))
        if len(self.backlash_deg) != 6 or not all(
            math.isfinite(v) and 0.0 <= v <= 10.0 for v in self.backlash_deg
        ):
            raise ConfigError(
                f"`backlash_deg` must hold 6 widths in [0, 10] deg, got {self.backlash_deg!r}"
            )
        if self.default_quantizer not in QUANTIZERS:
            raise ConfigError(
                f"`default_quantizer` {self.default_quantizer!r} must be one of {QUANTIZERS}"
            )
        if not isinstance(self.max_settles, int):
            raise ConfigError(f"`max_settles` must be an integer, got {self.max_settles!r}")

    @functools.cached_property
    def cycle_s(self) -> float:
        """The cycle [s]."""
        return self.cycle_ms / 1000.0

    @functools.cached_property
    def cycle_ns(self) -> int:
        """The cycle [ns]."""
        return round(self.cycle_ms * MS)

    @functools.cached_property
    def snapshot_age_ns(self) -> int:
        """Stamp minus snapshot time [ns]."""
        return round(self.snapshot_age_ms * MS)

    @functools.cached_property
    def max_stamp_gap_ns(self) -> int:
        """Largest stamp difference of consecutive joint states [ns]."""
        return round(self.max_stamp_gap_ms * MS)
