"""``manus certs --out DIR``: fresh lab credentials for the two-computer deployment.

Writes the CA, the two routers' certificates and every Zenoh user's password (see
:mod:`manus.certs`) into ``DIR``, which compose.yaml mounts as ``/etc/manus/lab``
(``MANUS_LAB_DIR``). Copy the same directory to both computers (or at least ``ca.pem``,
the router's own ``.pem``/``.key``, its users table and its services' passwords).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from manus.certs import write_lab


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Output directory and validity."""
    parser.add_argument("--out", required=True, type=Path, metavar="DIR", help="output directory")
    parser.add_argument(
        "--days", type=int, default=365, help="certificate validity [days] (default 365)"
    )
    parser.add_argument(
        "--arm-name",
        action="append",
        default=[],
        metavar="NAME",
        help="another host name or IP address of the arm computer (repeatable)",
    )


def run(args: argparse.Namespace) -> int:
    """Write the files; print each path."""
    for path in write_lab(args.out, days=args.days, arm_names=args.arm_name):
        print(path)
    print(f"certs: lab credentials in {args.out} (mount it as /etc/manus/lab)", file=sys.stderr)
    return 0
