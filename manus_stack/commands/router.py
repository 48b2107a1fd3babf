"""``manus router``: a Zenoh router in a Python process (no ``zenohd`` needed; SPEC 8.1).

Listens on ``--listen`` (default ``tcp/127.0.0.1:7447``, loopback only), scouting off,
until SIGINT/SIGTERM. Prints ``router: listening on ENDPOINT`` on stderr when ready.
"""

from __future__ import annotations

import argparse
import sys

from manus.node import wait_for_signal
from manus.session import DEFAULT_ROUTER_ENDPOINT, open_session, router_settings


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The endpoint to listen on."""
    parser.add_argument(
        "--listen",
        default=DEFAULT_ROUTER_ENDPOINT,
        metavar="ENDPOINT",
        help=f"endpoint (default {DEFAULT_ROUTER_ENDPOINT})",
    )


def run(args: argparse.Namespace) -> int:
    """Route until interrupted."""
    stop = wait_for_signal()
    session = open_session(router_settings(args.listen))
    try:
        print(f"router: listening on {args.listen}", file=sys.stderr, flush=True)
        stop.wait()
    finally:
        session.close()
    return 0
