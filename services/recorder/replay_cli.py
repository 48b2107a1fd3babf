"""``manus replay FILE.mcap``: publish a recording back onto the bus.

``--rate R`` scales time (2: twice as fast), ``--max`` publishes as fast as the bus takes
it, ``--only KEY...`` selects key suffixes (``state/joints``, ``can/**``), ``--prefix``
replays onto another arm's keys. ``--as SERVICE`` stands in for one service: publishes
only what it publishes, declares its liveliness tokens and answers its queryables from
the recording (:mod:`services.recorder.replay`); ``--hold S`` keeps the stand-in up S
seconds after the last message (``inf``: until SIGINT/SIGTERM; the default when there is
nothing to publish, as for the planner). Prints one ``stats:`` JSON line on standard
error (with ``--as``: how its queries were answered).

``--start S`` / ``--until S`` play a part (offsets from the first selected message),
``--loop N`` plays it N times, ``--paused`` starts paused; while it runs the replay answers
``<prefix>/replay/control`` (``manus playback pause|resume|step|seek S|rate R|status``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys

from manus.process import wait_for_signal
from manus.session import settings_from_env
from services.recorder.errors import RecordingError
from services.recorder.playback import Playback
from services.recorder.reading import Recording
from services.recorder.replay import REPLAYABLE, Replayer, schedule


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
        choices=sorted(REPLAYABLE),
        help="stand in for this service: its outputs, liveliness tokens and query answers",
    )
    parser.add_argument(
        "--hold",
        type=float,
        metavar="S",
        help="with --as: stay up S seconds after the last message (inf: until Ctrl-C; "
        "default 0, or inf when there is nothing to publish)",
    )
    parser.add_argument("--start", type=float, default=0.0, metavar="S", help="start offset [s]")
    parser.add_argument("--until", type=float, metavar="S", help="stop after this offset [s]")
    parser.add_argument("--loop", type=int, default=1, metavar="N", help="play N times")
    parser.add_argument(
        "--paused", action="store_true", help="start paused (manus playback resume|step)"
    )
    parser.add_argument("--connect", nargs="+", metavar="ENDPOINT", help="router endpoint(s)")
    parser.add_argument("--mode", choices=("client", "peer", "router"), help="zenoh mode")
    parser.add_argument("--prefix", help="publish under this prefix (default: the recording's)")


def run(args: argparse.Namespace) -> int:
    """Replay the file (standing in for a service with ``--as``); stop early on
    SIGINT/SIGTERM."""
    if args.hold is not None and (
        args.as_service is None or math.isnan(args.hold) or args.hold < 0
    ):
        raise RecordingError(f"--hold {args.hold}: needs --as SERVICE and a time >= 0 [s]")
    recording = Recording(args.file)
    items = schedule(recording, args.only, args.as_service)
    hold = args.hold if args.hold is not None else (math.inf if not items else 0.0)
    prefix = args.prefix or recording.info.prefix or None
    settings = settings_from_env(connect=args.connect, mode=args.mode, prefix=prefix)
    stop = wait_for_signal()
    with Replayer(settings, as_service=args.as_service, recording=recording) as replayer:
        who = ""
        if replayer.stand_in is not None:
            replies = replayer.stand_in.replies
            answering = ", ".join(
                f"{q} ({replies.recorded(q)} recorded)" for q in replies.queryables
            )
            who = f" as {args.as_service}" + (f"; answering {answering}" if answering else "")
        sys.stderr.write(
            f"replay: {len(items)} messages of {args.file} onto {settings.prefix}/**{who}\n"
        )
        sys.stderr.flush()
        stats = (
            replayer.play_controlled(
                items,
                Playback(
                    [i.offset_s for i in items],
                    rate=None if args.max else args.rate,
                    start_s=args.start,
                    until_s=args.until,
                    loops=args.loop,
                    paused=args.paused,
                ),
                stop=stop,
            )
            if items
            else replayer.play(items, stop=stop)
        )
        if args.as_service is not None and hold > 0 and not stop.is_set():
            stop.wait(None if math.isinf(hold) else hold)
        summary: dict[str, object] = dict(stats.__dict__)
        if replayer.stand_in is not None:
            summary["answers"] = {q: s.__dict__ for q, s in replayer.stand_in.replies.stats.items()}
            summary["bad_requests"] = replayer.stand_in.bad_requests
    sys.stderr.write(f"stats: {json.dumps(summary)}\n")
    return 0
