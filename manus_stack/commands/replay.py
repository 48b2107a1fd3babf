"""``manus replay FILE.mcap``: publish a recording onto the bus (see
:mod:`services.recorder.replay_cli`), or, with ``--check SERVICE``, feed its inputs to
that service's core and compare the outputs with the recorded ones
(:mod:`manus_stack.regression`): prints the result as JSON (with the float tolerance
and the largest deviation accepted), exits 1 on a difference; or,
with ``--view``, show it in Foxglove as ``manus view`` shows the live arm
(:mod:`manus_stack.view_replay`; nothing goes on the bus)."""

from __future__ import annotations

import argparse
import json
import sys

from manus.process import wait_for_signal
from manus_stack.regression import CHECKS
from services.recorder import replay_cli


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The live replay's arguments plus ``--check SERVICE``."""
    replay_cli.add_arguments(parser)
    parser.add_argument(
        "--check",
        choices=sorted(CHECKS),
        help="regression check instead of a live replay: the core's outputs vs the recording",
    )
    view = parser.add_argument_group("--view: in Foxglove, not on the bus")
    view.add_argument("--view", action="store_true", help="serve it to Foxglove (manus view)")
    view.add_argument("--view-port", type=int, default=8765, help="WebSocket port (0: any)")


def _view(args: argparse.Namespace) -> int:
    from manus_stack.view_replay import ViewReplay

    stop = wait_for_signal()
    with ViewReplay(args.file, port=args.view_port) as replay:
        sys.stderr.write(f"viewer: ws://127.0.0.1:{replay.port} (plays once a client subscribes)\n")
        sys.stderr.flush()
        if replay.wait_for_client(stop):
            stats = replay.play(
                rate=None if args.max else args.rate,
                start_s=args.start,
                until_s=args.until,
                loops=args.loop,
                paused=args.paused,
                stop=stop,
            )
            sys.stderr.write(f"stats: {json.dumps(stats.__dict__)}; Ctrl-C ends\n")
            sys.stderr.flush()
            stop.wait()
    return 0


def run(args: argparse.Namespace) -> int:
    """A live replay, or a regression check."""
    if args.view:
        return _view(args)
    if args.check is None:
        return replay_cli.run(args)
    result = CHECKS[args.check](args.file)
    out = {
        "service": result.service,
        "ok": result.ok,
        "inputs": result.inputs,
        "compared": result.compared,
        "recorded": result.recorded,
        "replayed": result.replayed,
        "difference": None if result.difference is None else str(result.difference),
        "tolerance": result.tolerance.relative,
        "deviation": result.deviation,
    }
    sys.stdout.write(json.dumps(out, indent=2) + "\n")
    return 0 if result.ok else 1
