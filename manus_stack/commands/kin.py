"""``manus kin``: forward and inverse kinematics, the Jacobian and the URDF, from the shell.

Thesis units at this edge: millimetres and degrees. A pose is printed as ``xyz_mm``,
``ypr_deg`` = [yaw, pitch, roll] (R = Rz(yaw) Ry(pitch) Rx(roll)) and ``pose`` (the
six together), and ``ik`` takes it in that order: X Y Z YAW PITCH ROLL
(:mod:`manus_stack.pose_args`, the command line's one order), so fk's output pastes
into ik.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from manus.config import UNFOLDED_Q_DEG, load_arm_config
from manus.kinematics import fk, ik_all, ik_nearest, jacobian
from manus.urdf import build_urdf
from manus_stack.pose_args import add_pose_argument, pose_fields, pose_from_values, pose_values


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare ``fk``, ``ik``, ``jacobian`` and ``urdf``."""
    parser.add_argument("--arm-config", help="arm geometry/limits JSON (default: thesis values)")
    sub = parser.add_subparsers(dest="kin_command", metavar="fk|ik|jacobian|urdf", required=True)
    p = sub.add_parser("fk", help="gripper pose of joint angles Q1..Q6 [deg]")
    p.add_argument("q", nargs=6, type=float, metavar="Q", help="DH joint angles [deg]")
    p = sub.add_parser(
        "ik",
        help="every IK branch of a pose X Y Z YAW PITCH ROLL, and the one nearest --near",
    )
    add_pose_argument(p)
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
            **pose_fields(T),
            "matrix": _rounded(M, 9),
            "matrix_units": "rotation: unitless; translation: mm",
        }
    elif args.kin_command == "ik":
        values = pose_values(args)
        assert values is not None  # a positional pose is always given
        T = pose_from_values(values)
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
