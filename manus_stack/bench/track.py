"""Tracking accuracy: the thesis square and circle in lock-step, default vs thesis mode.

Each run is a fresh lock-step arm (simulator + bridge + controller cores, simulated
clock; :class:`~manus_stack.controlled.ControlledArm`) started in the unfolded pose; the
path is planned by :class:`~services.planner.core.PlannerCore` from the first joint
state and executed by one controller mode. Figures per via point (the start knot, where
the arm already is, excluded):

- ``mean_mm`` / ``max_mm``: as the thesis measured, the distance between the forward
  kinematics of the encoder angles and the via point at the via point's time
  (``GoalResult.via_errors``);
- ``true_mean_mm`` / ``true_max_mm``: the simulator's true gripper position
  (``SimCore.truth``, sampled every ``TRUTH_STEP_S`` and interpolated) at the same
  instants (``GoalResult.via_stamps``), so backlash, joint 1's scale error and the
  encoder quantization count.

``variants`` measures the default mode with one of its ideas switched off (the choices
behind it), or with the belt play compensated (its widths taken as calibrated: the
simulator's); ``seeds`` repeats both modes on other simulator seeds (the drives' gain
errors differ); ``dropped_frames_1pct`` loses 1 % of the arm's frames (the controller
answers each gap with zeros and lets the trajectory's time wait).
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path as FilePath
from typing import Any

import numpy as np

from manus_stack.controlled import ControlledArm
from schemas.control import TrajectoryGoal
from services.controller.config import ControllerConfig
from services.simulator.config import SimConfig
from services.simulator.faults import FaultConfig, FrameFault

PATHS = FilePath(__file__).resolve().parents[2] / "paths"
TRUTH_STEP_S = 0.010
"""Sampling step of the simulator's truth [s]."""
TARGETS = {"default_mean_mm": 1.0, "default_max_mm": 2.5, "ratio_default_thesis_mean": 0.25}
VARIANTS: dict[str, dict[str, Any]] = {
    "rounding": {"default_quantizer": "rounding"},
    "error_feedback": {"default_quantizer": "error_feedback"},
    "no_observer": {"observer": False},
    "no_delay_compensation": {"delay_compensation": False},
    "backlash_compensation": {"backlash_deg": SimConfig().backlash_deg},
}
"""Default-mode variants: name -> ControllerConfig overrides."""
DROPS = FaultConfig(frames=(FrameFault(kind="drop", rate=0.01, start_ms=2000.0),))
"""1 % of the arm's frames lost from 2 s on (each costs the bridge a resync)."""


def track(
    path: str,
    mode: str,
    config: ControllerConfig | None = None,
    seed: int = 0,
    faults: FaultConfig | None = None,
) -> dict[str, Any]:
    """Run one path (``square`` or ``circle``) in one mode; its figures."""
    started = time.process_time()
    sim = SimConfig(start_pose="unfolded", seed=seed, faults=faults or FaultConfig())
    arm = ControlledArm(sim, config)
    arm.start()
    trajectory = arm.plan(PATHS / f"thesis_{path}.txt")
    goal = TrajectoryGoal(goal_id=f"{path}-{mode}", trajectory=trajectory, mode=mode)
    ack = arm.submit(goal)
    if not ack.accepted:
        raise RuntimeError(f"{goal.goal_id} refused: {ack.reason}")
    stamps: list[int] = []
    xyz: list[list[float]] = []
    started_ns = arm.ls.t_ns
    duration = trajectory.times[-1]
    limit = arm.ls.t_ns + round((2.0 * duration + goal.goal_time_tolerance + 5.0) * 1e9)
    while not arm.results(goal.goal_id) and arm.ls.t_ns < limit:
        arm.ls.run_for(TRUTH_STEP_S)
        truth = arm.ls.sim.truth()
        stamps.append(truth.stamp_ns)
        xyz.append(truth.xyz)
    if not arm.results(goal.goal_id):
        raise RuntimeError(f"{goal.goal_id}: no result within {(limit - started_ns) / 1e9:.0f} s")
    result = arm.results(goal.goal_id)[0]
    vias = np.asarray(trajectory.via_xyz, dtype=float)[1:]
    at = np.asarray(result.via_stamps[1:], dtype=float)
    grid, pos = np.asarray(stamps, dtype=float), np.asarray(xyz, dtype=float)
    true_xyz = np.column_stack([np.interp(at, grid, pos[:, k]) for k in range(3)])
    n = len(at)
    measured = np.asarray(result.via_errors[1:]) * 1000.0
    true = np.linalg.norm(true_xyz - vias[:n], axis=1) * 1000.0
    return {
        "mean_mm": _r(measured.mean()) if n else None,
        "max_mm": _r(measured.max()) if n else None,
        "true_mean_mm": _r(true.mean()) if n else None,
        "true_max_mm": _r(true.max()) if n else None,
        "via_points": n,
        "status": result.status,
        "reason": result.reason,
        "duration_s": _r(result.duration),
        "final_error_mm": _r(result.final_error * 1000.0),
        "via_mm": [_r(v, 2) for v in measured],
        "cpu_s": _r(time.process_time() - started, 2),
    }


def _r(value: float, digits: int = 3) -> float:
    return round(float(value), digits)


def run(quick: bool = False) -> dict[str, Any]:
    """Figures of both paths in both modes (plus variants and seeds unless ``quick``)."""
    out: dict[str, Any] = {}
    for path in ("square", "circle"):
        figures = {mode: track(path, mode) for mode in ("default", "thesis")}
        ratio = figures["default"]["mean_mm"] / figures["thesis"]["mean_mm"]
        entry: dict[str, Any] = {**figures, "ratio_default_thesis_mean": _r(ratio)}
        if not quick:
            entry["variants"] = {
                name: _summary(track(path, "default", ControllerConfig(**changes)))
                for name, changes in VARIANTS.items()
            }
            entry["dropped_frames_1pct"] = {
                mode: _summary(track(path, mode, faults=DROPS)) for mode in ("default", "thesis")
            }
            entry["seeds"] = {
                mode: [_summary(track(path, mode, seed=seed)) for seed in range(1, 4)]
                for mode in ("default", "thesis")
            }
        out[path] = entry
    out["targets"] = TARGETS
    out["met"] = all(
        out[p]["default"]["mean_mm"] <= TARGETS["default_mean_mm"]
        and out[p]["default"]["max_mm"] <= TARGETS["default_max_mm"]
        and out[p]["ratio_default_thesis_mean"] <= TARGETS["ratio_default_thesis_mean"]
        for p in ("square", "circle")
    )
    out["config"] = {k: v for k, v in dataclasses.asdict(ControllerConfig()).items() if k != "arm"}
    return out


def _summary(figures: dict[str, Any]) -> dict[str, Any]:
    keys = ("mean_mm", "max_mm", "true_mean_mm", "true_max_mm", "status", "duration_s")
    return {k: figures[k] for k in keys}
