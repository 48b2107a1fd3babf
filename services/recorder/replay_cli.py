"""``manus replay FILE.mcap``: publish a recording back onto the bus.

``--rate R`` scales time (2: twice as fast), ``--max`` publishes as fast as the bus takes
it, ``--only KEY...`` selects key suffixes (``state/joints``, ``can/**``), ``--as SERVICE``
publishes only what that service publishes (stand in for it), ``--prefix`` replays onto
another arm's keys. Prints one ``stats:`` JSON line on standard error.
"""

from __future__ import annotations

import argparse
import json
import sys

from manus.node import wait_for_signal
from manus.session import settings_from_env
from services.recorder.reading import Recording
from services.recorder.replay import SERVICE_OUTPUTS, Replayer, schedule


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The file, speed, selection and bus settings."""
    parser.add_argument("file", help="MCAP recording")
    speed = parser.add_mutually_exclusive_group()
    speed.add_argument("--rate", type=float, default=1.0, help="time scale (default 1: real time)")
    speed.add_argument("--max", action="store_true", help="as fast as possible")
    parser.add_argument("--only", nargs="+", metavar="KEY", help="key suffixes (or 'can/**')")
    parser.add_argument(
        "--as",
        dest="as_service",
        choices=sorted(SERVICE_OUTPUTS),
        help="replay only this service's outputs (stand in for it)",
    )
    parser.add_argument("--connect", nargs="+", metavar="ENDPOINT", help="router endpoint(s)")
    parser.add_argument("--mode", choices=("client", "peer", "router"), help="zenoh mode")
    parser.add_argument("--prefix", help="publish under this prefix (default: the recording's)")


def run(args: argparse.Namespace) -> int:
    """Replay the file; stop early on SIGINT/SIGTERM."""
    recording = Recording(args.file)
    items = schedule(recording, args.only, args.as_service)
    prefix = args.prefix or recording.info.prefix or None
    settings = settings_from_env(connect=args.connect, mode=args.mode, prefix=prefix)
    stop = wait_for_signal()
    with Replayer(settings) as replayer:
        sys.stderr.write(
            f"replay: {len(items)} messages of {args.file} onto {settings.prefix}/**\n"
        )
        sys.stderr.flush()
        stats = replayer.play(items, rate=None if args.max else args.rate, stop=stop)
    sys.stderr.write(f"stats: {json.dumps(stats.__dict__)}\n")
    return 0
