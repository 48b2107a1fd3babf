"""``manus replay FILE.mcap``: publish a recording onto the bus (see
:mod:`services.recorder.replay_cli`), or, with ``--check SERVICE``, feed its inputs to
that service's core and compare the outputs with the recorded ones
(:mod:`manus_stack.regression`): prints the result as JSON, exits 1 on a difference."""

from __future__ import annotations

import argparse
import json
import sys

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


def run(args: argparse.Namespace) -> int:
    """A live replay, or a regression check."""
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
    }
    sys.stdout.write(json.dumps(out, indent=2) + "\n")
    return 0 if result.ok else 1
