"""Settings of the follow source: standoff, speed profile, caps, the target's prediction
and faults (``services/controller/follow_source.py``, docs/follow.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from manus.errors import ConfigError
from manus.moved_objects import MOVE_BOUND_M

ORDERS = {"acceleration": 3, "jerk": 4}
"""The prediction's models: constant acceleration (white jerk) or constant jerk (white
snap), and the number of states each keeps per coordinate."""


def _check(name: str, value: float, lo: float, hi: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and lo <= value <= hi):
        raise ConfigError(f"follow: `{name}` must be in [{lo:g}, {hi:g}], got {value!r}")


@dataclass(frozen=True)
class FollowConfig:
    """How the controller follows a target.

    Attributes:
        standoff_m: default standoff from the target along the approach axis [m]: just
            outside the person's clearance (50 mm in the default scene).
        lean_margin_s: for a target on a person, the standoff grows by the target's
            predicted speed toward the arm times this [s]: the arm starts backing off
            before the person is in (the tracker's latency and the arm's 60-120 ms leave
            about 170 ms before the arm answers a lean).
        max_speed: speed cap of the tracked point, the most a goal may ask [m/s] (at most
            0.25, the reduced speed for robots working next to people).
        approach_speed: speed of the tracked point relative to the target while it
            closes in from afar [m/s].
        accel: acceleration cap of the tracked point [m/s^2].
        slow_radius_m: closer than this to the standoff point, the approach slows in
            proportion to the distance left (the braking curve also applies) [m] ...
        slow_floor: ... down to this share of ``approach_speed`` [-].
        person_slow_m: closer than this to a person's clearance, the motion relative to
            the target slows in proportion ... [m]
        person_floor: ... down to this share [-].
        hold_tolerance_m: the tracked point within this of the standoff point is holding [m].
        lock_m: a reference within this of where the target takes the standoff point
            goes there in one cycle (dead-beat); further, it closes in on the speed
            profile [m].
        lost_periods: the target is lost when no newer frame came for this many frame
            periods beyond its latency (a goal's ``lost_after`` overrides it) [-].
        max_target_speed: a target that moves faster than this between two frames jumped
            (a person's head moves slower) [m/s].
        jump_tolerance_m: the tracker's noise allowed on top of that between two frames [m].
        max_body_shift_m: the farthest a person's body may be reported from its place in
            the scene [m] (further: a jump; at most the collision model's bound).
        model: the prediction's model of the target's motion: ``acceleration``
            (constant acceleration) or ``jerk`` (constant jerk).
        process_noise: how freely the target leaves that model: the spectral density of
            the white noise on its highest derivative [m^2/s^5, m^2/s^7]; larger follows
            faster motion and passes more of the tracker's noise.
        noise_m: the tracker's noise, a standard deviation per coordinate [m].
        max_prediction_s: the target's motion is predicted over at most this [s] ...
        max_prediction_m: ... and by at most this far [m].
        reach_margin_deg: the standoff point is out of reach when the elbow would be
            this close to fully stretched (|q3 - 90 deg|) [deg].
    """

    standoff_m: float = 0.060
    lean_margin_s: float = 0.2
    max_speed: float = 0.200
    approach_speed: float = 0.100
    accel: float = 2.0
    slow_radius_m: float = 0.100
    slow_floor: float = 0.25
    person_slow_m: float = 0.150
    person_floor: float = 0.25
    hold_tolerance_m: float = 0.005
    lock_m: float = 0.010
    lost_periods: float = 2.0
    max_target_speed: float = 1.0
    jump_tolerance_m: float = 0.010
    max_body_shift_m: float = MOVE_BOUND_M
    model: str = "acceleration"
    process_noise: float = 0.1
    noise_m: float = 0.001
    max_prediction_s: float = 0.300
    max_prediction_m: float = 0.050
    reach_margin_deg: float = 8.0

    def __post_init__(self) -> None:
        _check("standoff_m", self.standoff_m, 0.0, 0.5)
        _check("lean_margin_s", self.lean_margin_s, 0.0, 2.0)
        _check("max_speed", self.max_speed, 0.001, 0.25)
        _check("approach_speed", self.approach_speed, 0.001, self.max_speed)
        _check("accel", self.accel, 0.01, 100.0)
        _check("slow_radius_m", self.slow_radius_m, 0.0, 1.0)
        _check("slow_floor", self.slow_floor, 0.01, 1.0)
        _check("person_slow_m", self.person_slow_m, 0.0, 1.0)
        _check("person_floor", self.person_floor, 0.01, 1.0)
        _check("hold_tolerance_m", self.hold_tolerance_m, 0.0001, 0.1)
        _check("lock_m", self.lock_m, 0.0, 0.1)
        _check("lost_periods", self.lost_periods, 1.0, 100.0)
        _check("max_target_speed", self.max_target_speed, 0.01, 10.0)
        _check("jump_tolerance_m", self.jump_tolerance_m, 0.0, 0.5)
        _check("max_body_shift_m", self.max_body_shift_m, 0.0, MOVE_BOUND_M)
        if self.model not in ORDERS:
            raise ConfigError(f"follow: `model` {self.model!r} must be one of {list(ORDERS)}")
        _check("process_noise", self.process_noise, 1e-6, 1e8)
        _check("noise_m", self.noise_m, 0.0, 0.1)
        _check("max_prediction_s", self.max_prediction_s, 0.0, 2.0)
        _check("max_prediction_m", self.max_prediction_m, 0.0, 0.5)
        _check("reach_margin_deg", self.reach_margin_deg, 0.0, 45.0)
