"""``manus planner``: run the planner service until SIGINT/SIGTERM.

Prints ``planner: serving <prefix>/planner/plan`` when ready and one ``stats:`` JSON line
(plans, refusals, bad payloads) on exit, both on standard error.
"""

from __future__ import annotations

import argparse
import json
import sys

from manus.config import load_arm_config
from manus.process import freeze_startup_heap, wait_for_signal
from manus.session import add_bus_arguments, bus_settings
from manus.world import WorldConfig
from schemas import endpoints as ep
from services.planner.config import PlannerConfig
from services.planner.plan_cli import add_scene_argument
from services.planner.shell import PlannerShell


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Bus settings (over the ``MANUS_ZENOH_*`` environment) and the arm config."""
    add_bus_arguments(parser)
    parser.add_argument("--arm-config", help="arm geometry/limits JSON (default: thesis values)")
    add_scene_argument(parser)
    parser.add_argument(
        "--object-stale-s",
        type=float,
        default=WorldConfig().stale_after_s,
        metavar="S",
        help="an object perception has not reported for longer than this is stale; a plan "
        "to it is refused (default %(default)g s; docs/objects.md)",
    )


def run(args: argparse.Namespace) -> int:
    """Serve plans until interrupted."""
    settings = bus_settings(args)
    config = PlannerConfig(
        arm=load_arm_config(args.arm_config),
        scene=args.scene,
        world=WorldConfig(stale_after_s=args.object_stale_s),
    )
    stop = wait_for_signal()
    with PlannerShell(settings, config) as shell:
        freeze_startup_heap()
        print(f"planner: serving {shell.node.keys(ep.PLAN)}", file=sys.stderr, flush=True)
        stop.wait()
        stats = {
            "plans": shell.plans,
            "refusals": shell.refusals,
            "bad_payloads": shell.node.bad_payload_count,
        }
    print(f"stats: {json.dumps(stats)}", file=sys.stderr, flush=True)
    return 0
