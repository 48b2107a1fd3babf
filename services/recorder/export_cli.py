"""``manus export FILE.mcap``: ``--json -o OUT.mcap`` (JSON-encoded MCAP for Foxglove),
``--candump -o OUT.log`` (raw CAN frames for CAN tools), or ``--info`` (channels, types,
counts and times as JSON on standard output)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from services.recorder.export import View, export_candump, export_json
from services.recorder.reading import Recording


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The file, the kind of export and the output."""
    parser.add_argument("file", help="MCAP recording")
    kind = parser.add_mutually_exclusive_group(required=True)
    kind.add_argument("--json", action="store_true", help="JSON-encoded MCAP (Foxglove)")
    kind.add_argument("--candump", action="store_true", help="candump .log (or .asc/.blf)")
    kind.add_argument("--info", action="store_true", help="print what the recording holds")
    parser.add_argument("-o", "--output", help="output file (default: next to FILE)")
    parser.add_argument("--can-channel", default="can0", help="channel name in the CAN log")


def run(args: argparse.Namespace, view: View | None = None) -> int:
    """Export or describe the recording (``view``: more channels for ``--json``)."""
    src = Path(args.file)
    if args.info:
        info = Recording(src).info
        out = json.dumps(
            {
                "prefix": info.prefix,
                "source": info.source,
                "messages": info.messages,
                "chunks": info.chunks,
                "duration_s": info.duration_s,
                "channels": {
                    c.suffix: {"type": c.schema_name, "messages": c.messages}
                    for c in info.channels.values()
                },
            },
            indent=2,
        )
        sys.stdout.write(out + "\n")
        return 0
    if args.json:
        dst = Path(args.output) if args.output else src.with_suffix(".json.mcap")
        stats = export_json(src, dst, view)
    else:
        dst = Path(args.output) if args.output else src.with_suffix(".log")
        stats = export_candump(src, dst, channel=args.can_channel)
    sys.stdout.write(json.dumps({"output": str(dst), **stats.__dict__}) + "\n")
    return 0
