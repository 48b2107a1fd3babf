"""``manus router``: a Zenoh router in a Python process (no ``zenohd`` needed).

Listens on ``--listen`` (default ``tcp/127.0.0.1:7447``, loopback only), scouting off,
until SIGINT/SIGTERM. Prints ``router: listening on ENDPOINT`` on stderr when ready.
``--config FILE`` runs a router of the two-computer deployment instead (endpoints, TLS,
access control from ``deploy/zenoh/router-*.json5``; ``MANUS_ZENOH_CREDENTIALS`` and
``MANUS_LAB_DIR`` as for every service, see :mod:`manus.session`).
"""

from __future__ import annotations

import argparse
import sys

from manus.process import wait_for_signal
from manus.realtime import add_realtime_argument, raise_priority, setting
from manus.session import (
    DEFAULT_ROUTER_ENDPOINT,
    build_config,
    open_session,
    router_settings,
    settings_from_env,
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The endpoint to listen on."""
    parser.add_argument(
        "--listen",
        default=DEFAULT_ROUTER_ENDPOINT,
        metavar="ENDPOINT",
        help=f"endpoint (default {DEFAULT_ROUTER_ENDPOINT})",
    )
    parser.add_argument(
        "--config",
        metavar="FILE",
        help="a Zenoh router config file (deploy/zenoh/router-*.json5); replaces --listen",
    )
    add_realtime_argument(parser)


def run(args: argparse.Namespace) -> int:
    """Route until interrupted."""
    priority = setting(args)
    stop = wait_for_signal()
    if args.config:
        settings = settings_from_env(config_file=args.config, mode="router")
        listen = build_config(settings).get_json("listen/endpoints")
    else:
        settings = router_settings(args.listen)
        listen = args.listen
    session = open_session(settings)
    raise_priority(priority, "manus router")  # every message of the arm's loop passes here
    try:
        print(f"router: listening on {listen}", file=sys.stderr, flush=True)
        stop.wait()
    finally:
        session.close()
    return 0
