"""``manus view``: the arm live in Foxglove (a WebSocket server, default 127.0.0.1:8765).

Prints ``viewer: ws://HOST:PORT`` on standard error when it serves, and one ``stats:`` JSON
line on exit (samples received and dropped, Foxglove messages, client events). ``--layout
FILE`` writes the Foxglove layout (``services/viewer/manus.layout.json``) and exits.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from manus.config import load_arm_config
from manus.process import freeze_startup_heap, wait_for_signal
from manus.session import add_bus_arguments, bus_settings
from services.viewer.layout import layout_json
from services.viewer.server import DEFAULT_BACKLOG, DEFAULT_HOST, DEFAULT_PORT
from services.viewer.shell import DEFAULT_QUEUE, ViewerShell


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Where to serve, buffer sizes, the layout, and bus settings."""
    parser.add_argument("--host", default=DEFAULT_HOST, help="address to serve on (loopback)")
    parser.add_argument("--port", type=int, default=DEFAULT_PORT, help="WebSocket port (0: any)")
    parser.add_argument(
        "--queue", type=int, default=DEFAULT_QUEUE, help="samples buffered before drops"
    )
    parser.add_argument(
        "--backlog", type=int, default=DEFAULT_BACKLOG, help="messages buffered per client"
    )
    parser.add_argument("--duration", type=float, help="stop after this many seconds")
    parser.add_argument("--layout", metavar="FILE", help="write the Foxglove layout and exit")
    parser.add_argument(
        "--scene",
        default="",
        help="scene drawn until the planner publishes another (default: $MANUS_SCENE, else "
        "the shipped one; 'none'; a file)",
    )
    parser.add_argument("--arm-config", help="arm geometry/limits JSON (default: thesis values)")
    add_bus_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Serve until interrupted (or write the layout)."""
    settings = bus_settings(args)
    if args.layout:
        Path(args.layout).write_text(layout_json(settings.prefix))
        print(f"layout: {args.layout}", file=sys.stderr)
        return 0
    stop = wait_for_signal()
    shell = ViewerShell(
        settings,
        host=args.host,
        port=args.port,
        queue_size=max(1, args.queue),
        backlog=max(1, args.backlog),
        arm=load_arm_config(args.arm_config),
        scene=args.scene,
    )
    try:
        freeze_startup_heap()
        print(f"viewer: ws://{args.host}:{shell.port}", file=sys.stderr, flush=True)
        stop.wait(args.duration)
    finally:
        shell.close()
    print(f"stats: {json.dumps(shell.stats())}", file=sys.stderr, flush=True)
    return 0
