"""``manus plot FILE.mcap [-o PNG]``: the path in the yz plane (planned vs executed), joint
references vs actuals, commanded increments, the via-point error table and, with the
simulator's truth, the run's clearances, as one PNG. Prints ``plot: PNG`` and the summary
as JSON: the via-point errors and the tightest clearance on the truth (``clearance``:
the pair, its distance and the clearance it needs, whether every clearance was kept)."""

from __future__ import annotations

import argparse
import json
import sys

from manus.config import load_arm_config
from services.recorder.plot import plot_recording


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The file and the output."""
    parser.add_argument("file", help="MCAP recording")
    parser.add_argument("-o", "--output", help="PNG to write (default: FILE with .png)")
    parser.add_argument("--title", help="figure title (default: the file name)")
    parser.add_argument(
        "--arm-config",
        help="the recorded arm's geometry JSON (default: $MANUS_ARM_CONFIG, else thesis values)",
    )
    parser.add_argument(
        "--scene",
        default="",
        help="the scene until the recording's first planner/scene_state (default: "
        "$MANUS_SCENE, else the shipped one)",
    )


def run(args: argparse.Namespace) -> int:
    """Draw the plot."""
    summary = plot_recording(
        args.file,
        args.output,
        arm=load_arm_config(args.arm_config),
        title=args.title,
        scene=args.scene,
    )
    sys.stderr.write(f"plot: {summary.output}\n")
    out = {
        "output": summary.output,
        "goals": summary.goals,
        "via_points": len(summary.via_errors_mm),
        "mean_mm": None if summary.goals == 0 else round(summary.mean_mm, 3),
        "max_mm": None if summary.goals == 0 else round(summary.max_mm, 3),
        "clearance": None,
    }
    worst = summary.clearance
    if worst is not None:
        out["clearance"] = {
            "distance_mm": round(worst.distance * 1e3, 1),
            "required_mm": round(worst.check.required * 1e3, 1),
            "body": worst.check.body,
            "other": worst.check.other,
            "class": worst.check.cls,
            "time_s": round(worst.time, 3),
            "kept": summary.clearance_broken == 0,
        }
    sys.stdout.write(json.dumps(out) + "\n")
    return 0
