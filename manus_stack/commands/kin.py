"""``manus kin``: forward and inverse kinematics, the Jacobian and the URDF, from the shell.

Thesis units at this edge: millimetres and degrees. Orientation is printed as
``ypr_deg`` = [yaw, pitch, roll] (R = Rz(yaw) Ry(pitch) Rx(roll)); ``ik`` takes it in
via-point column order: YAW ROLL PITCH.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from manus.config import UNFOLDED_Q_DEG, load_arm_config
from manus.kinematics import fk, ik_all, ik_nearest, jacobian
from manus.orientation import matrix_to_ypr, pose_matrix
from manus.urdf import build_urdf


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare ``fk``, ``ik``, ``jacobian`` and ``urdf``."""
    parser.add_argument("--arm-config", help="arm geometry/limits JSON (default: thesis values)")
    sub = parser.add_subparsers(dest="kin_command", metavar="fk|ik|jacobian|urdf", required=True)
    p = sub.add_parser("fk", help="gripper pose of joint angles Q1..Q6 [deg]")
    p.add_argument("q", nargs=6, type=float, metavar="Q", help="DH joint angles [deg]")
    p = sub.add_parser("ik", help="every IK branch of a pose, and the one nearest --near")
    for name in ("x", "y", "z"):
        p.add_argument(name, type=float, help=f"{name.upper()} [mm]")
    for name in ("yaw", "roll", "pitch"):
        p.add_argument(name, type=float, help=f"{name} [deg]")
    p.add_argument(
        "--near",
        nargs=6,
        type=float,
        metavar="Q",
        default=list(UNFOLDED_Q_DEG),
        help="reference configuration [deg] (default: the unfolded pose %(default)s)",
    )
    p = sub.add_parser("jacobian", help="geometric Jacobian at Q1..Q6 [deg] (m/rad, rad/rad)")
    p.add_argument("q", nargs=6, type=float, metavar="Q")
    p = sub.add_parser("urdf", help="write the URDF of the configured arm")
    p.add_argument("-o", "--output", help="file to write (default: standard output)")


def _rounded(a: np.ndarray, digits: int = 6) -> list[object]:
    return (np.round(np.asarray(a, dtype=float), digits) + 0.0).tolist()  # type: ignore[no-any-return]


def run(args: argparse.Namespace) -> int:
    """Run one ``manus kin`` subcommand; print JSON on standard output."""
    cfg = load_arm_config(args.arm_config)
    if args.kin_command == "fk":
        T = fk(np.radians(args.q), cfg)
        M = T.copy()
        M[:3, 3] *= 1000.0
        out: dict[str, object] = {
            "xyz_mm": _rounded(T[:3, 3] * 1000.0),
            "ypr_deg": _rounded(np.degrees(matrix_to_ypr(T[:3, :3]))),
            "matrix": _rounded(M, 9),
            "matrix_units": "rotation: unitless; translation: mm",
        }
    elif args.kin_command == "ik":
        ypr = (math.radians(args.yaw), math.radians(args.pitch), math.radians(args.roll))
        T = pose_matrix(np.array([args.x, args.y, args.z]) / 1000.0, ypr)
        sols = ik_all(T, cfg)
        nearest = ik_nearest(T, np.radians(args.near), cfg)
        out = {
            "solutions_deg": _rounded(np.degrees(sols.q)),
            "branches": sols.branch.tolist(),
            "nearest_deg": _rounded(np.degrees(nearest)),
        }
    elif args.kin_command == "jacobian":
        out = {
            "jacobian": _rounded(jacobian(np.radians(args.q), cfg), 9),
            "rows": "vx vy vz [m/s per rad/s], wx wy wz [rad/s per rad/s]",
        }
    else:
        text = build_urdf(cfg)
        if args.output:
            Path(args.output).write_text(text)
            print(f"urdf: {args.output}", file=sys.stderr)
        else:
            sys.stdout.write(text)
        return 0
    print(json.dumps(out))
    return 0
