"""``manus record``: record the bus to MCAP until SIGINT/SIGTERM (or ``--duration``);
``manus record --recover FILE``: rescue a recording that was never closed;
``manus record --ring S``: the flight recorder (:mod:`services.recorder.flight_shell`),
the last S seconds in memory, written to ``--out-dir`` when a trigger fires;
``manus record --trigger REASON``: ask a running flight recorder to write now.

Prints ``recorder: recording <prefix>/** to FILE`` when ready and one ``stats:`` JSON line
(messages, bytes, samples received, liveliness changes, per-key counts) on exit, both on
standard error.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from manus.process import freeze_startup_heap, wait_for_signal
from manus.session import add_bus_arguments, bus_settings
from services.recorder.recover import recover
from services.recorder.shell import RecorderShell
from services.recorder.split import KeyFilter
from services.recorder.writer import DEFAULT_CHUNK_SIZE, DEFAULT_FLUSH_INTERVAL_NS


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Output file, recovery, chunking and bus settings."""
    parser.add_argument("-o", "--output", help="MCAP file (default: manus-YYYYmmdd-HHMMSS.mcap)")
    parser.add_argument(
        "--recover",
        metavar="FILE",
        help="rescue the complete chunks of a crashed recording, and its journal "
        "(FILE.open: the chunk that was open), into -o "
        "(default: FILE with .recovered.mcap) and exit",
    )
    parser.add_argument("--duration", type=float, help="stop after this many seconds")
    parser.add_argument(
        "--chunk-kib", type=int, default=DEFAULT_CHUNK_SIZE // 1024, help="largest chunk [KiB]"
    )
    parser.add_argument(
        "--flush-ms",
        type=float,
        default=DEFAULT_FLUSH_INTERVAL_NS / 1e6,
        help="close and flush a chunk at least this often [ms]: the most a power loss "
        "loses (a killed recorder's open chunk is in FILE.open)",
    )
    parser.add_argument(
        "--split-mib", type=float, default=0.0, help="write in parts of this size [MiB] "
        "(FILE_000.mcap, FILE_001.mcap, ...; 0: one file)"
    )  # fmt: skip
    parser.add_argument(
        "--split-s", type=float, default=0.0, help="... or of this duration [s] (0: one file)"
    )
    parser.add_argument(
        "--include", nargs="+", default=[], metavar="KEY", help="record only these key "
        "suffixes (patterns: 'state/*', 'controller/**')"
    )  # fmt: skip
    parser.add_argument(
        "--exclude", nargs="+", default=[], metavar="KEY", help="never record these (e.g. 'can/*')"
    )
    flight = parser.add_argument_group("flight recorder")
    flight.add_argument(
        "--ring", type=float, metavar="S", help="keep the last S seconds in memory; write them "
        "(and --after S more) to --out-dir when a trigger fires"
    )  # fmt: skip
    flight.add_argument("--after", type=float, default=5.0, metavar="S", help="seconds after [s]")
    flight.add_argument("--ring-mib", type=float, default=64.0, help="memory cap [MiB]")
    flight.add_argument("--out-dir", default="flight", help="where flight files go")
    flight.add_argument(
        "--warning-codes",
        type=int,
        nargs="*",
        default=[],
        metavar="CODE",
        help="arm warning codes that trigger (e.g. 3: motor blocked); errors always do",
    )
    flight.add_argument(
        "--trigger", metavar="REASON", help="ask the running flight recorder to write now; exit"
    )
    add_bus_arguments(parser)


def _send_trigger(args: argparse.Namespace) -> int:
    from manus.node import Node, now_ns
    from schemas.endpoints import FLIGHT_TRIGGER
    from schemas.flight import FlightTrigger

    with Node("flight_trigger", bus_settings(args), liveliness=False) as node:
        pub = node.publisher(node.keys(FLIGHT_TRIGGER))
        time.sleep(0.3)  # let the subscription reach the publisher before the one sample
        pub.put(FlightTrigger(stamp_ns=now_ns(), seq=0, source="manus record", reason=args.trigger))
        time.sleep(0.1)
    print(f"trigger: sent ({args.trigger})", file=sys.stderr)
    return 0


def _flight(args: argparse.Namespace) -> int:
    from services.recorder.flight import FlightConfig, TriggerRules
    from services.recorder.flight_shell import FlightShell

    config = FlightConfig(
        ring_s=args.ring,
        after_s=args.after,
        cap_bytes=round(args.ring_mib * 1024 * 1024),
        rules=TriggerRules(warning_codes=tuple(args.warning_codes)),
    )
    stop = wait_for_signal()
    shell = FlightShell(bus_settings(args), args.out_dir, config)
    try:
        freeze_startup_heap()
        print(
            f"flight recorder: last {args.ring:g} s of {shell.node.keys.all} "
            f"(cap {args.ring_mib:g} MiB) -> {args.out_dir}",
            file=sys.stderr,
            flush=True,
        )
        stop.wait(args.duration)
    finally:
        shell.close()
    print(f"stats: {json.dumps(shell.stats())}", file=sys.stderr, flush=True)
    return 0


def _recover(args: argparse.Namespace) -> int:
    src = Path(args.recover)
    dst = Path(args.output) if args.output else src.with_suffix(".recovered.mcap")
    stats = recover(src, dst)
    print(f"recovered: {dst}", file=sys.stderr)
    print(json.dumps({"output": str(dst), **stats.__dict__}))
    return 0


def run(args: argparse.Namespace) -> int:
    """Record until interrupted, or recover a file."""
    if args.recover:
        return _recover(args)
    if args.trigger is not None:
        return _send_trigger(args)
    if args.ring is not None:
        return _flight(args)
    settings = bus_settings(args)
    output = args.output or time.strftime("manus-%Y%m%d-%H%M%S.mcap")
    stop = wait_for_signal()
    keys = KeyFilter(args.include, args.exclude) if args.include or args.exclude else None
    shell = RecorderShell(
        settings,
        output,
        chunk_size=max(1, args.chunk_kib) * 1024,
        flush_interval_ns=max(1, round(args.flush_ms * 1e6)),
        split_bytes=round(args.split_mib * 1024 * 1024),
        split_s=args.split_s,
        keys=keys,
    )
    try:
        freeze_startup_heap()
        print(f"recorder: recording {shell.node.keys.all} to {output}", file=sys.stderr, flush=True)
        stop.wait(args.duration)
    finally:
        stats = shell.close()
    summary = {
        "output": output,
        "messages": stats.messages,
        "bytes": stats.bytes,
        "received": shell.received,
        "liveliness_changes": shell.liveliness_changes,
        "reserved_dropped": shell.reserved_dropped,
        "filtered": shell.filtered,
        "parts": [str(p) for p in getattr(shell.writer, "parts", [])],
        "not_msgpack": stats.not_msgpack,
        "write_errors": shell.write_errors,
        "keys": {k: c.messages for k, c in stats.channels.items()},
    }
    print(f"stats: {json.dumps(summary)}", file=sys.stderr, flush=True)
    return 0
