"""``manus plan FILE``: plan a via-point file in-process and print the trajectory as JSON
(the ``manus plan`` command is :mod:`manus_stack.commands.plan`, which adds the goals).

The trajectory is checked against the scene (``--scene``); the smallest clearance and
where it occurs go into the JSON (``clearance``) and on one line of standard error.

Thesis units at this edge: degrees and millimetres. One row per knot (knot i is via
point i; time 0 is the start). A path that cannot be planned exits 1 with the reason on
one line of standard error (via :func:`manus_stack.cli.main`'s error handling).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

import numpy as np

from manus.config import UNFOLDED_Q_DEG, load_arm_config
from manus.viapoints import load_path
from schemas.collision import ClearanceReport
from schemas.planning import PlanRequest, ViaPointPath
from services.planner.config import PlannerConfig
from services.planner.core import PlannerCore
from services.planner.errors import PlanningError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """FILE, ``--start-joints``, ``--quintic``, ``--speed-scaling``, ``--preview``."""
    parser.add_argument(
        "file", nargs="?", help="via-point file (14 columns, mm, deg, s); or give a goal option"
    )
    parser.add_argument(
        "--start-joints",
        nargs=6,
        type=float,
        metavar="Q",
        default=list(UNFOLDED_Q_DEG),
        help="start configuration, DH joint angles [deg] (default: the unfolded pose %(default)s)",
    )
    parser.add_argument("--quintic", action="store_true", help="quintic segments, not cubic")
    parser.add_argument(
        "--speed-scaling",
        action="store_true",
        help="stretch time to respect the joint speed/acceleration limits instead of refusing",
    )
    parser.add_argument(
        "--preview", action="store_true", help="include the Cartesian preview (every 60 ms)"
    )
    parser.add_argument("--arm-config", help="arm geometry/limits JSON (default: thesis values)")
    add_scene_argument(parser)


def add_scene_argument(parser: argparse.ArgumentParser) -> None:
    """``--scene``: the scene file every plan is checked against."""
    parser.add_argument(
        "--scene",
        default="",
        help="scene file (docs/scene.md); 'none': no collision check "
        "(default: $MANUS_SCENE, else the shipped wheelchair scene)",
    )


def clearance_json(report: ClearanceReport | None) -> dict[str, Any] | None:
    """The smallest clearance in thesis units (mm, s), or None."""
    if report is None:
        return None
    return {
        "distance_mm": round(report.distance * 1e3, 3),
        "required_mm": round(report.required * 1e3, 3),
        "body": report.body,
        "other": report.other,
        "class": report.cls,
        "time_s": round(report.time, 6),
    }


def _deg(a: list[Any]) -> list[Any]:
    out: list[Any] = (np.round(np.degrees(np.asarray(a, dtype=float)), 9) + 0.0).tolist()
    return out


def _mm(a: list[Any]) -> list[Any]:
    out: list[Any] = (np.round(np.asarray(a, dtype=float) * 1000.0, 6) + 0.0).tolist()
    return out


def run(args: argparse.Namespace) -> int:
    """Plan ``args.file`` from ``args.start_joints``; print JSON."""
    config = PlannerConfig(arm=load_arm_config(args.arm_config), scene=args.scene)
    motion = ViaPointPath(
        path=load_path(args.file),
        interpolation="quintic" if args.quintic else "cubic",
        speed_scaling=args.speed_scaling,
    )
    request = PlanRequest(
        motion,
        start=[math.radians(q) for q in args.start_joints],
        preview_dt=0.06 if args.preview else 0.0,
    )
    reply = PlannerCore(config).plan(request)
    if reply.error is not None:
        raise PlanningError(reply.error)
    traj = reply.trajectory
    assert traj is not None
    out: dict[str, Any] = {
        "source": args.file,
        "interpolation": motion.interpolation,
        "start_deg": _deg(request.start or []),
        "times_s": [round(t, 9) for t in traj.times],
        "positions_deg": _deg(traj.positions),
        "velocities_deg_s": _deg(traj.velocities),
        "via_xyz_mm": _mm(traj.via_xyz),
        "via_lines": traj.via_lines,
        "time_scale": traj.time_scale,
        "notes": traj.notes,
        "clearance": clearance_json(traj.clearance),
        "scene_version": traj.scene_version,
    }
    if traj.accelerations:
        out["accelerations_deg_s2"] = _deg(traj.accelerations)
    if args.preview:
        out["preview_dt_s"] = traj.preview_dt
        out["preview_xyz_mm"] = _mm(traj.preview_xyz)
    sys.stdout.write(json.dumps(out) + "\n")
    if traj.clearance is not None:
        c = traj.clearance
        sys.stderr.write(
            f"smallest clearance: {c.body} {c.distance * 1e3:.1f} mm from {c.other} "
            f"({c.cls}: needs {c.required * 1e3:.0f} mm) at t = {c.time:.2f} s\n"
        )
    return 0
