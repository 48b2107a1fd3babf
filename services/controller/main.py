"""``manus controller``: run the controller service until SIGINT/SIGTERM.

Prints ``controller: serving <prefix>/controller/goal`` when ready and one ``stats:``
JSON line (messages sent per key, bad payloads) on exit, both on standard error.
"""

from __future__ import annotations

import argparse
import json
import sys

from manus.config import load_arm_config
from manus.process import freeze_startup_heap, wait_for_signal
from manus.realtime import add_realtime_argument, raise_priority, setting
from manus.session import add_bus_arguments, bus_settings
from schemas import endpoints as ep
from services.controller.config import QUANTIZERS, ControllerConfig
from services.controller.jog_config import JogConfig
from services.controller.shell import ControllerShell


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Bus settings (over the ``MANUS_ZENOH_*`` environment), arm config, loop options."""
    add_bus_arguments(parser)
    parser.add_argument("--arm-config", help="arm geometry/limits JSON (default: thesis values)")
    parser.add_argument(
        "--quantizer",
        choices=QUANTIZERS,
        default="cartesian",
        help="rounding of the default mode (default: cartesian)",
    )
    parser.add_argument(
        "--thesis-gain", type=float, default=2.5, help="K of the thesis mode [1/s] (default 2.5)"
    )
    parser.add_argument("--jog-timeout-ms", type=float, default=JogConfig.timeout_ms,
                        help="live control's deadman [ms] (default 150)")  # fmt: skip
    parser.add_argument("--jog-max-linear-mm-s", type=float, default=JogConfig.max_linear * 1e3,
                        help="Cartesian jog speed at the top level [mm/s] (default 150, "
                             "at most 250)")  # fmt: skip
    add_realtime_argument(parser)


def run(args: argparse.Namespace) -> int:
    """Serve goals until interrupted."""
    settings = bus_settings(args)
    priority = setting(args)
    config = ControllerConfig(
        arm=load_arm_config(args.arm_config),
        default_quantizer=args.quantizer,
        thesis_gain=args.thesis_gain,
        jog=JogConfig(timeout_ms=args.jog_timeout_ms, max_linear=args.jog_max_linear_mm_s / 1e3),
    )
    stop = wait_for_signal()
    with ControllerShell(settings, config) as shell:
        freeze_startup_heap()
        raise_priority(priority, "manus controller")
        print(f"controller: serving {shell.node.keys(ep.GOAL)}", file=sys.stderr, flush=True)
        stop.wait()
        with shell.node.lock:
            stats = {"sent": dict(shell.sent), "bad_payloads": shell.node.bad_payload_count}
    print(f"stats: {json.dumps(stats)}", file=sys.stderr, flush=True)
    return 0
