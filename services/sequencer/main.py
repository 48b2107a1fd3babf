"""``manus sequencer``: run the sequencer service (the supervisor API) until SIGINT/SIGTERM.

Prints ``sequencer: serving <prefix>/sequencer/submit`` when ready and one ``stats:``
JSON line (tasks started, refused, bad payloads) on exit, both on standard error.
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
from services.sequencer.config import SequencerConfig
from services.sequencer.shell import SequencerShell


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Bus settings (over the ``MANUS_ZENOH_*`` environment) and the arm config."""
    add_bus_arguments(parser)
    parser.add_argument("--arm-config", help="arm geometry/limits JSON (default: thesis values)")
    add_realtime_argument(parser)


def run(args: argparse.Namespace) -> int:
    """Serve tasks until interrupted."""
    settings = bus_settings(args)
    priority = setting(args)
    config = SequencerConfig(arm=load_arm_config(args.arm_config))
    stop = wait_for_signal()
    with SequencerShell(settings, config) as shell:
        freeze_startup_heap()
        raise_priority(priority, "manus sequencer")
        print(f"sequencer: serving {shell.node.keys(ep.SUBMIT)}", file=sys.stderr,
              flush=True)  # fmt: skip
        stop.wait()
        stats = {
            "tasks": shell.submitted,
            "refused": shell.refused,
            "bad_payloads": shell.node.bad_payload_count,
        }
    print(f"stats: {json.dumps(stats)}", file=sys.stderr, flush=True)
    return 0
