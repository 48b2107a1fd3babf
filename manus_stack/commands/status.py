"""``manus status [--json] [--wait S]``: services alive and where, bridge health, arm status.

Exits 0 when every service of ``schemas.keys.SERVICES`` but the optional ones
(simulator, recorder) is alive or off on purpose (its ``disabled/<service>/<why>`` token is
up: the guardian beside a single-reader bridge channel, shown as ``OFF`` with why), 1
otherwise (a quick check for scripts).
"""

from __future__ import annotations

import argparse
import json
import sys

from manus.node import Node
from manus.session import add_bus_arguments, bus_settings
from manus_stack.status import collect, format_status

OPTIONAL = ("simulator", "recorder")
"""Services whose absence does not make ``manus status`` fail."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Output form, waiting time and the bus options."""
    parser.add_argument("--json", action="store_true", help="one JSON object instead of text")
    parser.add_argument(
        "--wait", type=float, default=1.0, metavar="S", help="listen this long [s] (default 1)"
    )
    add_bus_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Ask the bus and print."""
    with Node("status", bus_settings(args), liveliness=False) as node:
        status = collect(node, args.wait)
    if args.json:
        sys.stdout.write(json.dumps(status) + "\n")
    else:
        sys.stdout.write(format_status(status) + "\n")
    needed = {n: info for n, info in status["services"].items() if n not in OPTIONAL}
    return 0 if all(i["alive"] or i["disabled"] is not None for i in needed.values()) else 1
