"""``manus schemas --out DIR``: write the JSON Schema of every bus message.

One ``<type>.schema.json`` per message type, ``index.json`` (key suffix -> file) and
``supervisor.schema.json`` (the sequencer's API in one document). Prints the files.
``--check`` instead compares ``schemas/supervisor.schema.json`` with the code (exit 1 when
it is out of date).
"""

from __future__ import annotations

import argparse

from schemas.export import SUPERVISOR_FILE, dumps, supervisor_document, write_schemas


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Output directory or check mode."""
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--out", metavar="DIR", help="directory to write the schemas into")
    group.add_argument("--check", action="store_true",
                       help=f"check that {SUPERVISOR_FILE.name} is current")  # fmt: skip
    group.add_argument("--update", action="store_true",
                       help=f"rewrite the checked-in {SUPERVISOR_FILE.name}")  # fmt: skip


def run(args: argparse.Namespace) -> int:
    """Write, check or update."""
    text = dumps(supervisor_document())
    if args.check:
        current = SUPERVISOR_FILE.read_text(encoding="utf-8") if SUPERVISOR_FILE.exists() else ""
        if current != text:
            print(f"{SUPERVISOR_FILE} is out of date: run `manus schemas --update`")
            return 1
        print(f"{SUPERVISOR_FILE} is current")
        return 0
    if args.update:
        SUPERVISOR_FILE.write_text(text, encoding="utf-8")
        print(SUPERVISOR_FILE)
        return 0
    for path in write_schemas(args.out):
        print(path)
    return 0
