"""``manus scene show|check``: draw the arm in a scene, or validate a scene file.

``show`` writes a PNG of the scene (objects by class, zones, the arm's collision bodies
at ``--joints``, degrees, default the unfolded pose, a legend) and prints the tightest
clearance; ``check`` reads a scene file and prints what it holds as JSON (its file format
and scene version among it; exit 1, one line naming file, line and field, when it is
malformed or touches the arm's base).
"""

from __future__ import annotations

import argparse
import json
import math
import sys

import numpy as np

from manus.collision import CollisionModel
from manus.config import UNFOLDED_Q_DEG, load_arm_config
from manus.scene import describe, scene_from_setting


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``show`` and ``check``."""
    sub = parser.add_subparsers(dest="scene_command", metavar="show|check", required=True)
    for name, text in (
        ("show", "draw the arm in the scene (PNG)"),
        ("check", "validate a scene file; print what it holds as JSON"),
    ):
        p = sub.add_parser(name, help=text, description=text)
        p.add_argument("--arm-config", help="arm geometry/limits JSON (default: thesis values)")
        p.add_argument(
            "--scene",
            default="",
            help="scene file (default: $MANUS_SCENE, else the shipped wheelchair scene)",
        )
        if name == "show":
            p.add_argument(
                "--joints",
                nargs=6,
                type=float,
                metavar="Q",
                default=list(UNFOLDED_Q_DEG),
                help="DH joint angles [deg] (default: the unfolded pose %(default)s)",
            )
            p.add_argument("--opening", type=float, default=0.0, help="gripper opening [mm]")
            p.add_argument("-o", "--output", default="scene.png", help="PNG to write")


def run(args: argparse.Namespace) -> int:
    """Draw or check."""
    scene = scene_from_setting(args.scene or "")
    if scene is None:
        print("manus scene: no scene ('none')", file=sys.stderr)
        return 1
    arm = load_arm_config(args.arm_config)
    CollisionModel(scene, arm)  # refuses an object on the arm's base
    if args.scene_command == "check":
        print(json.dumps(describe(scene)))
        return 0
    from manus_stack.scene_view import draw_scene

    q = [math.radians(v) for v in args.joints]
    picture = draw_scene(scene, np.asarray(q), args.output, arm=arm, opening=args.opening * 1e-3)
    print(picture.clearance)
    print(f"plot: {args.output}")
    return 0
