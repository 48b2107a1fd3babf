"""``manus playback pause|resume|step|seek S|rate R|status``: control a running replay.

Queries ``<prefix>/replay/control`` (``schemas.playback``) and prints the replay's status as
JSON; exits 1 when the request was refused (a step while playing, a seek outside the
selection, a rate <= 0) or no replay answered.
"""

from __future__ import annotations

import argparse
import json
import sys

from manus.node import Node, QueryError
from manus.session import add_bus_arguments, bus_settings
from schemas.endpoints import PLAYBACK_CONTROL
from schemas.playback import ACTIONS, PlaybackControl, PlaybackStatus


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The action, its value, and bus settings."""
    parser.add_argument("action", choices=ACTIONS)
    parser.add_argument("value", nargs="?", type=float, default=0.0, help="seek: S; rate: R")
    parser.add_argument("--timeout", type=float, default=3.0, help="how long to wait [s]")
    add_bus_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Send the request; print the status."""
    with Node("playback", bus_settings(args), liveliness=False) as node:
        try:
            status = node.query(
                node.keys(PLAYBACK_CONTROL),
                PlaybackControl(action=args.action, value=args.value),
                PlaybackStatus,
                timeout=args.timeout,
            )
        except QueryError as exc:
            sys.stderr.write(f"manus playback: {exc} (is a manus replay running?)\n")
            return 1
    sys.stdout.write(json.dumps(status.to_dict()) + "\n")
    return 0 if status.ok else 1
