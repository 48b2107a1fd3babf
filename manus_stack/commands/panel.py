"""``manus panel``: the web page for the person in the chair (docs/panel.md).

Serves the panel on ``http://127.0.0.1:PORT/`` until Ctrl-C or SIGTERM: big buttons for
the tasks of a task directory, the speed level, a hold-to-move jog pad, STOP, the arm's
state and the last trouble in plain words; touch, mouse, keyboard and single-switch
scanning. It talks to the stack through the supervisor and jog APIs only
(:mod:`manus_stack.panel.bus`).
"""

from __future__ import annotations

import argparse
import asyncio
import signal
import sys

from manus.errors import ConfigError
from manus.session import add_bus_arguments, bus_settings
from manus_stack.panel.bus import PanelBus
from manus_stack.panel.server import PageSettings, PanelServer, serve
from manus_stack.panel.tasks import DEFAULT_DIR, load_buttons
from manus_stack.panel.view import PanelView


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The port, the task directory, the speed level, scanning, and the bus options."""
    parser.add_argument("--port", type=int, default=8080, help="port on 127.0.0.1 (8080)")
    parser.add_argument("--tasks", metavar="DIR", default=str(DEFAULT_DIR),
                        help="task directory: panel.toml and its task files "
                             "(default: the shipped one)")  # fmt: skip
    parser.add_argument("--level", type=int, default=1,
                        help="set the jog's speed level at start (1, the slowest; 0: leave "
                             "it as it is)")  # fmt: skip
    parser.add_argument("--scan", action="store_true",
                        help="pages start in single-switch scanning mode")  # fmt: skip
    parser.add_argument("--scan-ms", type=int, default=1500, metavar="MS",
                        help="scanning: how long each control is highlighted (1500)")  # fmt: skip
    add_bus_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Serve until Ctrl-C or SIGTERM."""
    from pathlib import Path

    if not 0 < args.port < 65536:
        raise ConfigError(f"--port {args.port} is outside 1..65535")
    if not 200 <= args.scan_ms <= 20000:
        raise ConfigError(f"--scan-ms {args.scan_ms} is outside 200..20000 ms")
    if args.level < 0:
        raise ConfigError(f"--level {args.level} must be 0 (leave it) or a level from 1")
    buttons = load_buttons(Path(args.tasks))
    view = PanelView(buttons)
    server: PanelServer | None = None

    def changed() -> None:
        if server is not None:
            server.changed()

    bus = PanelBus(bus_settings(args), view, changed)
    try:
        server = PanelServer(bus, PageSettings(scan=args.scan, scan_ms=args.scan_ms))
        if args.level:
            ack = bus.set_level(args.level)
            if ack is not None and not ack.accepted:
                raise ConfigError(f"--level {args.level}: the controller refused: {ack.reason}")
        asyncio.run(_serve(server, args.port))
    finally:
        bus.close()
    return 0


async def _serve(server: PanelServer, port: int) -> None:
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)

    def ready() -> None:
        sys.stdout.write(f"panel: http://127.0.0.1:{port}/\n")
        sys.stdout.flush()

    await serve(server, port, stop, ready)
