"""``manus record``: record the bus to MCAP until SIGINT/SIGTERM (or ``--duration``);
``manus record --recover FILE``: rescue a recording that was never closed.

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

from manus.node import freeze_startup_heap, wait_for_signal
from manus.session import add_bus_arguments, bus_settings
from services.recorder.recover import recover
from services.recorder.shell import RecorderShell
from services.recorder.writer import DEFAULT_CHUNK_SIZE, DEFAULT_FLUSH_INTERVAL_NS


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Output file, recovery, chunking and bus settings."""
    parser.add_argument("-o", "--output", help="MCAP file (default: manus-YYYYmmdd-HHMMSS.mcap)")
    parser.add_argument(
        "--recover",
        metavar="FILE",
        help="rescue the complete chunks of a crashed recording into -o "
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
        help="close and flush a chunk at least this often [ms]: the most a crash loses",
    )
    add_bus_arguments(parser)


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
    settings = bus_settings(args)
    output = args.output or time.strftime("manus-%Y%m%d-%H%M%S.mcap")
    stop = wait_for_signal()
    shell = RecorderShell(
        settings,
        output,
        chunk_size=max(1, args.chunk_kib) * 1024,
        flush_interval_ns=max(1, round(args.flush_ms * 1e6)),
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
        "not_msgpack": stats.not_msgpack,
        "write_errors": shell.write_errors,
        "keys": {k: c.messages for k, c in stats.channels.items()},
    }
    print(f"stats: {json.dumps(summary)}", file=sys.stderr, flush=True)
    return 0
