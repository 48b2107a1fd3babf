"""Live control figures: latency, stops, straight lines, against the arm's own Cartesian mode.

Every figure is judged on the simulator's truth (:mod:`manus_stack.jog_lockstep`: the
lock-step simulator, bridge and controller cores, a jog sender publishing at 20 Hz):

- ``start_latency_ms``: from a command's publication (the arm at rest, the publication
  at phases spread over the 60 ms cycle) to the first true motion (a motor faster than
  0.5 deg/s);
- ``stop_latency_ms``: from the deadman's expiry (the last command + ``jog_timeout``) or
  from a zero command's publication to the arm at rest (every motor under 0.5 deg/s);
  ``zeros_acting_ms``: from the expiry to the moment the first zero command acts;
  ``stop_floor_ms``: what no PC program can beat on this arm, per trial: the wait from
  the trigger to the next sync (the arm takes one reply per 60 ms cycle), the 20 ms
  until the reply acts, and the drives' first-order lag (tau ``transient_tau_ms``) from
  the true motor speed at that moment down to 0.5 deg/s; ``over_floor_ms``: the stop
  latency minus that floor (negative for the deadman when it is judged before the
  nominal expiry: commands are dated on the 60 ms grid of the joint states);
- ``straight_line_drift_mm`` and ``orientation_drift_deg`` per speed level: a unitless
  x jog in the base frame until the true gripper has moved 100 mm; the largest true
  distance from the line, and the largest true change of orientation;
- ``drink_mode``: the same x jog (level 3) in drink mode while the cup turns about the
  base z at 18 deg/s (full deflection): ``tilt_drift_deg`` is the largest change of the
  cup's tilt (the base's z axis seen from the gripper; yaw does not change it);
- ``cpu_ms_per_cycle``: the controller core's CPU time (its thread's) per joint state
  while jogging;
- ``cartesian_mode_0x371``: the same 100 mm line driven by the arm's own Cartesian mode
  as the simulator models it (a PC answering every sync with a 0x371 frame, X
  increments of 0.022 mm per 20 ms), open loop as a joystick would, and closed loop on
  the X/Y/Z and angles the arm reports in that mode.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from manus.orientation import ypr_to_matrix
from manus.protocol import XYZ_UNIT_MM, FrameId, MoveCommand, move_frame
from manus_stack.jog_lockstep import REST_DEG_S, JogArm, TruthSample, line_drift
from schemas import endpoints as ep
from schemas.jog import JogLevel
from services.simulator.config import SimConfig
from services.simulator.core import MS, SimCore
from services.simulator.scripted import ScriptedPc

TARGETS = {
    "stop_latency_max_ms": 120.0,
    "over_floor_max_ms": 10.0,  # two truth samples (5 ms each)
    "straight_line_drift_mm": 1.0,
    "orientation_drift_deg": 0.5,
}
LINE_M = 0.100
X = [1.0, 0.0, 0.0]
CAP_M_S = 0.150


def _stats(values_ms: list[float]) -> dict[str, float]:
    a = np.asarray(values_ms)
    return {
        "p50": round(float(np.median(a)), 1),
        "p99": round(float(np.percentile(a, 99)), 1),
        "max": round(float(a.max()), 1),
        "n": len(values_ms),
    }


def _arm(level: int = 5) -> JogArm:
    arm = JogArm()
    arm.start()
    arm.query(ep.JOG_LEVEL, JogLevel(level=level))
    arm.run(0.3)
    return arm


def _phase_to(arm: JogArm, phase_ms: float) -> None:
    """Run to ``phase_ms`` after the newest joint state's stamp (the cycle grid)."""
    js = arm.core.last_js
    assert js is not None
    target = js.stamp_ns + round(phase_ms * MS)
    while target <= arm.ls.t_ns:
        target += 60 * MS
    arm.run((target - arm.ls.t_ns) / 1e9)


def stop_floor_ms(arm: JogArm, trigger_ns: int) -> float:
    """The fastest stop any PC program could give from ``trigger_ns`` (module docstring):
    next sync, + 20 ms until the reply acts, + the drives' lag down to rest."""
    sync = next(f.t_ns for f in arm.ls.arm_frames if f.id == FrameId.SYNC and f.t_ns >= trigger_ns)
    acts = sync + 20 * MS
    speed = next(s.speed for s in arm.samples if s.t_ns >= acts)
    tau_ms = arm.ls.sim.config.transient_tau_ms
    fall_ms = tau_ms * math.log(speed / REST_DEG_S) if speed > REST_DEG_S else 0.0
    return (acts - trigger_ns) / 1e6 + fall_ms


def latencies(trials: int) -> dict[str, Any]:
    """Start and stop latencies over ``trials`` phases of the cycle."""
    starts, deadman, release, acting = [], [], [], []
    floors: dict[str, list[float]] = {"deadman": [], "release": []}
    over: dict[str, list[float]] = {"deadman": [], "release": []}
    arm = _arm()
    for k in range(trials):
        phase = 60.0 * (k + 0.37) / trials
        _phase_to(arm, phase)
        t0 = arm.ls.t_ns
        arm.stream(0.4, units="unitless", linear=X if k % 2 == 0 else [-1.0, 0.0, 0.0])
        moved = arm.first_motion_from(t0)
        assert moved is not None, "the arm did not move"
        starts.append((moved - t0) / 1e6)
        if k % 2 == 0:  # the sender goes silent: the deadman
            expiry = arm.sent[-1][0] + arm.core.config.jog.timeout_ns
            arm.run(0.6)
            rest = arm.rest_from(expiry)
            first_zero = next(
                f.t_ns for f in arm.ls.bridge_frames if f.id == FrameId.JOINT and f.t_ns >= expiry
                and not any(f.data)
            )  # fmt: skip
            acting.append((first_zero + 20 * MS - expiry) / 1e6)
            assert rest is not None
            deadman.append((rest - expiry) / 1e6)
            floors["deadman"].append(stop_floor_ms(arm, expiry))
            over["deadman"].append(deadman[-1] - floors["deadman"][-1])
            arm.stream(0.2)  # release, so the next trial may move
        else:
            _phase_to(arm, (phase * 7.0) % 60.0)
            t1 = arm.ls.t_ns
            arm.stream(0.6)
            rest = arm.rest_from(t1)
            assert rest is not None
            release.append((rest - t1) / 1e6)
            floors["release"].append(stop_floor_ms(arm, t1))
            over["release"].append(release[-1] - floors["release"][-1])
    return {
        "start_latency_ms": _stats(starts),
        "stop_latency_ms": {"deadman": _stats(deadman), "release": _stats(release)},
        "zeros_acting_ms": _stats(acting),
        "stop_floor_ms": {k: _stats(v) for k, v in floors.items()},
        "over_floor_ms": {k: _stats(v) for k, v in over.items()},
    }


def _tilt_deg(a: TruthSample, b: TruthSample) -> float:
    up_a, up_b = a.R.T @ np.array([0.0, 0.0, 1.0]), b.R.T @ np.array([0.0, 0.0, 1.0])
    return math.degrees(math.acos(max(-1.0, min(1.0, float(up_a @ up_b)))))


def line(level: int, **extra: Any) -> dict[str, Any]:
    """A 100 mm unitless x jog at ``level``: drift, turn, CPU per cycle."""
    arm = _arm(level)
    first = len(arm.samples)
    x0 = arm.samples[-1].xyz[0]
    spent: list[float] = []
    step = arm.core.on_joint_state

    def timed(js: Any) -> Any:
        t = time.thread_time_ns()
        out = step(js)
        spent.append((time.thread_time_ns() - t) / 1e9)
        return out

    arm.core.on_joint_state = timed  # type: ignore[method-assign]
    arm.stream(30.0, until=lambda s: s.xyz[0] - x0 >= LINE_M, units="unitless", linear=X, **extra)
    seg = arm.samples[first:]
    drift, along, turned = line_drift(seg, np.array(X))
    moving = [s for s in seg if not s.at_rest]
    return {
        "drift_mm": round(drift * 1e3, 3),
        "orientation_drift_deg": round(turned, 3),
        "tilt_drift_deg": round(max(_tilt_deg(seg[0], s) for s in seg), 3),
        "mm_s": round(along * 1e3 / ((moving[-1].t_ns - moving[0].t_ns) / 1e9), 1),
        "cpu_ms_per_cycle": round(1e3 * float(np.mean(spent)), 3),
        "cpu_ms_p99": round(1e3 * float(np.percentile(spent, 99)), 3),
    }


def cartesian_mode(speed_m_s: float, closed_loop: bool, seed: int = 0) -> dict[str, Any]:
    """The 100 mm x line driven by the arm's own Cartesian mode (module docstring)."""
    core = SimCore(SimConfig(start_pose="unfolded", seed=seed))
    pc = ScriptedPc(core)
    zero = move_frame(MoveCommand(FrameId.CARTESIAN, 0, (0,) * 6, 0))
    pc.wait_ready()
    pc.run_cycles(3, zero)  # Cartesian mode, valid X/Y/Z fields
    start = pc.cycles[-1].fields
    unit = XYZ_UNIT_MM / 1000.0
    n = max(-127, min(127, round(speed_m_s / (unit / 0.02))))

    def answer(_: Any) -> Any:
        axes = [n, 0, 0, 0, 0, 0]
        if closed_loop:  # half the reported cross-track and angle errors back per cycle
            now = pc.cycles[-1].fields  # (3 ticks a cycle, fields in increment units)
            for i in range(1, 6):
                axes[i] = max(-10, min(10, round(-0.5 * (now[i] - start[i]) / 3)))
        return move_frame(MoveCommand(FrameId.CARTESIAN, 0, tuple(axes), 0))  # type: ignore[arg-type]

    samples = []
    x0 = float(core.truth().xyz[0])
    t_end = core.time_ns + 30_000 * MS
    while core.time_ns < t_end:
        pc.run(core.time_ns + 5 * MS, answer)
        truth = core.truth()
        state = core.state_at(core.time_ns)
        samples.append(
            TruthSample(
                core.time_ns,
                np.asarray(truth.xyz),
                ypr_to_matrix(*truth.ypr),
                float(np.max(np.abs(state.speed_deg_s))),
                0.0,
                np.asarray(truth.q_true),
            )
        )
        if truth.xyz[0] - x0 >= LINE_M:
            break
    drift, _, turned = line_drift(samples, np.array(X))
    return {
        "drift_mm": round(drift * 1e3, 3),
        "orientation_drift_deg": round(turned, 3),
        "mm_s": round(n * unit / 0.02 * 1e3, 1),
    }


def run(quick: bool = False) -> dict[str, Any]:
    """All figures (``quick``: fewer latency trials)."""
    out: dict[str, Any] = latencies(8 if quick else 30)
    levels = {level: line(level) for level in range(1, 6)}
    out["straight_line_drift_mm"] = {f"level_{k}": v["drift_mm"] for k, v in levels.items()}
    out["orientation_drift_deg"] = {
        f"level_{k}": v["orientation_drift_deg"] for k, v in levels.items()
    }
    out["speed_mm_s"] = {f"level_{k}": v["mm_s"] for k, v in levels.items()}
    drink = line(3, drink=True, angular=[0.0, 0.0, 1.0])
    out["drink_mode"] = {k: drink[k] for k in ("drift_mm", "tilt_drift_deg", "mm_s")}
    out["cpu_ms_per_cycle"] = {
        "mean": round(float(np.mean([v["cpu_ms_per_cycle"] for v in levels.values()])), 3),
        "p99": round(max(v["cpu_ms_p99"] for v in levels.values()), 3),
    }
    out["cartesian_mode_0x371"] = {
        loop: {
            f"level_{k}": cartesian_mode(CAP_M_S * k / 5, loop == "closed_loop")
            for k in range(1, 6)
        }
        for loop in ("open_loop", "closed_loop")
    }
    out["targets"] = TARGETS
    out["met"] = {
        "stop_latency": out["stop_latency_ms"]["deadman"]["max"] <= TARGETS["stop_latency_max_ms"],
        "stop_at_floor": max(v["max"] for v in out["over_floor_ms"].values())
        <= TARGETS["over_floor_max_ms"],
        "straight_line": max(out["straight_line_drift_mm"].values())
        <= TARGETS["straight_line_drift_mm"],
        "orientation": max(out["orientation_drift_deg"].values())
        <= TARGETS["orientation_drift_deg"],
    }
    return out
