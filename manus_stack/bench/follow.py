"""Following a moving target, judged on the simulator's truth (docs/follow.md, Measured).

Every run is lock-step (:class:`manus_stack.follow_lockstep.FollowArm`: simulator,
bridge and controller cores; the simulator's tracker at 30 Hz, 40 ms latency):

- ``sinusoid``: a free target (on no person) sways 100 mm peak to peak (+-50 mm) along
  the chair's y at 0.1, 0.2 and 0.5 Hz, the gripper on it (standoff 0). RMS and max of
  the true tracking error over 10 s, the lag (the shift of the true path against the
  true target that fits best), and ``floor``: what the 60 ms cycle and the 21 speeds
  allow (:mod:`.follow_floor`, the same target and orientation), and the ratio. The
  controller is told its tracker is noiseless (``model`` jerk, ``process_noise`` 1e4,
  ``noise_m`` 0.2 mm); ``ideal_arm``: the same on an arm without gain errors, belt play or
  joint-1 scale error (what the encoders cannot see); ``play_set``: the controller told
  the belts' play (``backlash_deg``); ``noisy_tracker``: 1 mm of tracker noise, the
  controller's defaults.
- ``step``: the free target jumps 50 mm along y: settling time (into 2 mm for good),
  overshoot along the step.
- ``faults``: the user's mouth lost for 1 s (the tracker silent): from the timeout (the
  last frame's arrival plus two periods) to the zero command acting on the arm, and to
  the true motors at rest; the arm's true largest speed after the window and before a
  fresh goal (it must stay still); the same for a tracker jumping 200 mm (another face).
- ``mouth``: the cup's rim (60 mm past the gripper) held at the default standoff from the
  swaying mouth (+-15 mm y, +-5 mm z at 0.25 Hz), the user leaning forward 50 mm (and
  15 mm down) over 1 s and, suddenly, over 0.6 s.
- ``close``: the closer approach (rim 30 mm from the mouth, its clearance 20 mm), the
  largest true speed of the rim toward or along the target inside 100 mm of it, over
  0.3 s (over one cycle it dithers by up to 10 mm/s: each joint has 21 speeds).
- ``safety`` over every run: the arm's bodies' and the rim's true distance to the person
  against the person's clearance (50 mm; the closer approach's rim: 20 mm); entries, and
  entries the arm's own motion made (the person leaning into the arm is the rest).
- ``cpu_ms_per_cycle``: the controller core's CPU time per joint state while following,
  the target frames taken since the last joint state included; ``goal_query_max``: the
  largest CPU time of a follow goal's query (its admission, where the guard builds what
  the first command needs). The start-up heap frozen as the service freezes its own
  (:class:`Timed`); ``cycles_with_a_collection``: cycles in which a garbage collection
  ran (it walks every young object of this process: the simulator's, the bridge's, the
  probe's), ``p99_less_collections``: the p99 with their time taken out.
- ``streamed_via_points``: 10 via points appended one by one while the arm moves, against
  the same path planned whole (:mod:`.follow_stream`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from manus.config import DEFAULT_ARM, UNFOLDED_Q_DEG
from manus.kinematics import fk
from manus.protocol import FrameId
from manus.scene import default_scene
from manus_stack.bench import follow_cpu, follow_stream
from manus_stack.bench.follow_cpu import Timed
from manus_stack.bench.follow_floor import floor_errors, pose_ik
from manus_stack.follow_lockstep import FollowArm, FollowSample
from schemas import endpoints as ep
from schemas.target import TargetPose
from services.controller.config import ControllerConfig
from services.controller.follow_config import FollowConfig
from services.simulator.config import SimConfig
from services.simulator.target_config import LostWindow, TargetConfig, TargetMove

TARGETS = {
    "rms_0.1_hz_mm": 3.0,
    "rms_0.2_hz_mm": 8.0,
    "floor_ratio": 1.5,
    "zeros_acting_ms": 120.0,
    "entries": 0,
    "cpu_ms_p99": 1.0,
}
FREE_XYZ_MM = (500.0, -200.0, 1150.0)
"""The free target's rest, chair frame [mm]: in front of the user, above the table's edge."""
MOUTH_START_DEG = (51.2, 17.4, -4.2, -51.9, -98.2, -10.3)
"""The arm holding a cup 250 mm in front of the default user's mouth, its rim (60 mm past
the gripper) toward it (DH [deg])."""
RIM = [0.0, 0.0, 0.06]
NOISELESS = FollowConfig(model="jerk", process_noise=1e4, noise_m=0.0002)
IDEAL = {"speed_gain_error": 0.0, "backlash_deg": (0.0,) * 6, "joint1_scale_error": 0.0}
PLAY = (0.15, 0.05, 0.05, 0.3, 0.3, 0.3)
"""The simulator's belt play [deg] (its default), as a calibration would give it."""


SAMPLES: list[list[FollowSample]] = []
"""Every run's truth samples (the safety figures are taken over all of them)."""


def _arm(
    target: TargetConfig, start: tuple[float, ...], follow: FollowConfig, **sim: Any
) -> FollowArm:
    extra = {k: v for k, v in sim.items() if k != "backlash_ctl"}
    config = ControllerConfig(follow=follow, backlash_deg=sim.get("backlash_ctl", (0.0,) * 6))
    arm = FollowArm(SimConfig(start_pose=start, target=target, **extra), config)
    arm.start()
    arm.run(0.3)
    SAMPLES.append(arm.samples)
    return arm


def _rms(values: list[float]) -> float:
    return float(np.sqrt(np.mean(np.square(values)))) if values else math.nan


def _free_start() -> tuple[tuple[float, ...], np.ndarray, np.ndarray]:
    """The arm on the free target's rest (DH [deg]), the orientation held and the rest in
    the base frame."""
    mount = default_scene().mount
    rest = (np.linalg.inv(mount) @ np.array([*np.array(FREE_XYZ_MM) / 1e3, 1.0]))[:3]
    q = np.radians(UNFOLDED_Q_DEG)
    R = fk(q, DEFAULT_ARM)[:3, :3]
    q0 = pose_ik(q, rest, R, np.zeros(3), DEFAULT_ARM)
    return tuple(float(v) for v in np.degrees(q0)), R, rest


def _lag_ms(samples: list[FollowSample], step_ms: float) -> float:
    """The shift of the true path against the true standoff point that fits best [ms]
    (positive: the arm behind)."""
    pts = np.array([s.point for s in samples])
    aims = np.array([s.aim for s in samples])
    best = (math.inf, 0)
    for k in range(-30, 31):
        a = aims[max(0, -k) : len(aims) - max(0, k)]
        p = pts[max(0, k) : len(pts) - max(0, -k)]
        r = float(np.sqrt(np.mean(np.sum((a - p) ** 2, axis=1))))
        best = min(best, (r, k))
    return best[1] * step_ms


def sinusoid(hz: float, variant: str = "default", seconds: float = 10.0) -> dict[str, Any]:
    """The free target on a sinusoid (module docstring)."""
    start, R, rest = _free_start()
    noise = 1.0 if variant == "noisy_tracker" else 0.0
    target = TargetConfig(
        enabled=True, xyz_mm=FREE_XYZ_MM, body="", sway_mm=(0.0, 50.0, 0.0), sway_hz=hz,
        noise_mm=noise,
    )  # fmt: skip
    follow = FollowConfig() if variant == "noisy_tracker" else NOISELESS
    sim: dict[str, Any] = dict(IDEAL) if variant == "ideal_arm" else {}
    if variant == "play_set":
        sim["backlash_ctl"] = PLAY
    arm = _arm(target, start, follow, **sim)
    timer = Timed(arm)
    assert arm.follow(standoff=0.0).accepted
    arm.run(2.0)
    first = len(arm.samples)
    arm.run(seconds)
    timer.done()
    seg = arm.samples[first:]
    errors = [s.error for s in seg]
    out = {
        "rms_mm": round(_rms(errors) * 1e3, 2),
        "max_mm": round(max(errors) * 1e3, 2),
        "lag_ms": _lag_ms(seg, arm.sample_ns / 1e6),
        "ended": [r.cause for r in arm.follow_results()],
    }
    if variant == "default":
        t0 = seg[0].t_ns / 1e9
        phase = 2.0 * math.pi * hz

        def at(t: float) -> np.ndarray:
            return np.asarray(rest + np.array([0.0, 0.05 * math.sin(phase * (t0 + t)), 0.0]))

        q0 = pose_ik(np.radians(start), at(0.0), R, np.zeros(3), DEFAULT_ARM)
        floor = floor_errors(at, R, q0, seconds, DEFAULT_ARM)
        floor_rms = _rms(floor.tolist())
        out["floor_rms_mm"] = round(floor_rms * 1e3, 2)
        out["floor_max_mm"] = round(float(floor.max()) * 1e3, 2)
        out["ratio"] = round(_rms(errors) / floor_rms, 2)
    return out


def step() -> dict[str, Any]:
    """The free target jumps 50 mm (module docstring)."""
    start, _, _ = _free_start()
    at = 3.0
    target = TargetConfig(
        enabled=True, xyz_mm=FREE_XYZ_MM, body="",
        moves=(TargetMove(at_s=at, by_mm=(0.0, 50.0, 0.0)),),
    )  # fmt: skip
    arm = _arm(target, start, NOISELESS)
    assert arm.follow(standoff=0.0, max_target_speed=2.0).accepted
    arm.run(at + 3.0 - arm.ls.t_ns / 1e9)
    after = [s for s in arm.samples if s.t_ns >= at * 1e9]
    final = np.array(after[-1].aim)
    settle = at
    for s in after:
        if s.error > 0.002:
            settle = s.t_ns / 1e9
    along = [float(np.array(s.point)[1] - final[1]) for s in after]
    return {
        "settling_s": round(settle - at, 3),
        "overshoot_mm": round(max(0.0, *along) * 1e3, 2),
        "ended": [r.cause for r in arm.follow_results()],
    }


def _fault_stop(arm: FollowArm, timeout_ns: int) -> dict[str, Any]:
    """From ``timeout_ns``: the zero command acting, the true motors at rest."""
    zero = next(
        f.t_ns for f in arm.ls.bridge_frames
        if f.id == FrameId.JOINT and f.t_ns >= timeout_ns and not any(f.data)
    )  # fmt: skip
    after = [s for s in arm.samples if s.t_ns >= timeout_ns]
    rest = next((s.t_ns for s in after if s.speed < 0.5), None)
    return {
        "zeros_acting_ms": round((zero + 20_000_000 - timeout_ns) / 1e6, 1),
        "true_rest_ms": None if rest is None else round((rest - timeout_ns) / 1e6, 1),
        "speed_then_deg_s": round(after[0].speed, 1),
    }


def _mouth(**target: Any) -> TargetConfig:
    base: dict[str, Any] = {"enabled": True, "sway_mm": (0.0, 15.0, 5.0), "sway_hz": 0.25}
    return TargetConfig(**(base | target))


def faults() -> dict[str, Any]:
    """The target lost for 1 s, then a jump (module docstring)."""
    out: dict[str, Any] = {}
    lost_at = 6.0
    target = _mouth(lost=(LostWindow(at_s=lost_at, for_s=1.0),))
    arm = _arm(target, MOUTH_START_DEG, FollowConfig())
    assert arm.follow(offset=RIM).accepted
    arm.run(lost_at + 2.0 - arm.ls.t_ns / 1e9)
    frames = [(t, m) for t, k, m in arm.ls.messages if k == ep.TARGET]
    last = max(t for t, m in frames if isinstance(m, TargetPose) and m.stamp_ns < lost_at * 1e9)
    timeout = last + round(2e9 / target.rate_hz)  # the last frame's arrival + two periods
    lost = _fault_stop(arm, timeout)
    lost["ended"] = [r.cause for r in arm.follow_results()]
    back = [s.speed for s in arm.samples if s.t_ns >= (lost_at + 1.2) * 1e9]
    lost["true_speed_after_window_deg_s"] = round(max(back), 2)
    ack = arm.follow(goal_id="f2", offset=RIM)
    arm.run(2.0)
    lost["fresh_goal"] = "accepted" if ack.accepted else ack.reason
    lost["fresh_goal_error_mm"] = round(arm.samples[-1].error * 1e3, 2)
    out["lost"] = lost
    jump_at = 5.0
    target = _mouth(body="", moves=(TargetMove(at_s=jump_at, by_mm=(0.0, 200.0, 0.0)),))
    arm = _arm(target, MOUTH_START_DEG, FollowConfig())
    assert arm.follow(offset=RIM).accepted
    arm.run(jump_at + 1.0 - arm.ls.t_ns / 1e9)
    arrival = min(
        t
        for t, k, m in arm.ls.messages
        if k == ep.TARGET and isinstance(m, TargetPose) and m.stamp_ns >= jump_at * 1e9
    )
    jump = _fault_stop(arm, arrival)
    jump["ended"] = [r.cause for r in arm.follow_results()]
    out["jump"] = jump
    return out


def mouth(lean_s: float) -> dict[str, Any]:
    """The rim held at the standoff from the swaying mouth, a lean (module docstring)."""
    lean = TargetMove(at_s=6.0, by_mm=(50.0, 0.0, -15.0), over_s=lean_s)
    arm = _arm(_mouth(moves=(lean,)), MOUTH_START_DEG, FollowConfig())
    timer = Timed(arm)
    assert arm.follow(offset=RIM).accepted
    arm.run(4.0)
    first = len(arm.samples)
    arm.run(6.0)
    timer.done()
    seg = arm.samples[first:]
    before = [s.error for s in seg if s.t_ns < 6.0e9]
    return {
        "sway_rms_mm": round(_rms(before) * 1e3, 2),
        "lean_max_error_mm": round(max(s.error for s in seg) * 1e3, 1),
        "rim_min_mm": round(min(s.rim for s in seg) * 1e3, 1),
        "arm_min_mm": round(min(s.person for s in seg if s.person is not None) * 1e3, 1),
        "ended": [r.cause for r in arm.follow_results()],
    }


def close() -> dict[str, Any]:
    """The closer approach (module docstring)."""
    arm = _arm(_mouth(), MOUTH_START_DEG, FollowConfig())
    assert arm.follow(offset=RIM, close=True, standoff=0.03, close_clearance=0.02).accepted
    arm.run(12.0)
    near = [s for s in arm.samples if s.aim is not None and math.dist(s.point, s.target) < 0.1]
    toward = []
    for a, b in zip(near, near[30:], strict=False):  # over 0.3 s (the speed steps dither)
        dt = (b.t_ns - a.t_ns) / 1e9
        if dt <= 0.301:
            v = (np.array(b.point) - np.array(a.point)) / dt
            away = np.array(a.point) - np.array(a.target)
            u = away / np.linalg.norm(away)
            out = max(0.0, float(v @ u))
            toward.append(float(np.linalg.norm(v - out * u)))
    return {
        "rim_min_mm": round(min(s.rim for s in arm.samples if s.aim is not None) * 1e3, 1),
        "speed_inside_100mm_max_mm_s": round(max(toward) * 1e3, 1) if toward else None,
        "final_error_mm": round(arm.samples[-1].error * 1e3, 2),
        "ended": [r.cause for r in arm.follow_results()],
    }


def safety(clearance: float = 0.05) -> dict[str, Any]:
    """Entries into the person's clearance over every run so far (module docstring)."""
    samples = [s for run in SAMPLES for s in run if s.aim is not None]
    arm = [s for s in samples if s.person is not None and s.person < clearance]
    rim = [s for s in samples if s.rim < clearance]
    return {
        "samples": len(samples),
        "arm_entries": len(arm),
        "arm_min_mm": round(min(s.person for s in samples if s.person is not None) * 1e3, 1),
        "rim_entries": len(rim),
        "rim_entries_by_the_arm": sum(s.closing for s in rim),
    }


def run(quick: bool = False) -> dict[str, Any]:
    """Every figure (``quick``: the sinusoids' default variant only)."""
    SAMPLES.clear()
    follow_cpu.clear()
    out: dict[str, Any] = {"targets": TARGETS}
    variants = ["default"] if quick else ["default", "ideal_arm", "play_set", "noisy_tracker"]
    out["sinusoid"] = {v: {f"{hz}_hz": sinusoid(hz, v) for hz in (0.1, 0.2, 0.5)} for v in variants}
    out["step"] = step()
    out["faults"] = faults()
    out["mouth"] = {"lean_1s": mouth(1.0), "lean_0.6s": mouth(0.6)}
    person = safety()
    out["close"] = close()
    out["safety"] = {"default_clearance": person, "close_approach": safety(0.02)}
    out["streamed_via_points"] = follow_stream.figures()
    out["cpu_ms_per_cycle"] = follow_cpu.figures()
    return out
