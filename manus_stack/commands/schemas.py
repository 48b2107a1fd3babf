"""``manus schemas --out DIR``: write the JSON Schema of every bus message.

One ``<type>.schema.json`` per message type, ``index.json`` (key suffix -> file) and
``supervisor.schema.json`` (the sequencer's API in one document). Prints the files.
``--update`` rewrites the repository's files derived from the endpoint table (the
supervisor document, the key table of docs/architecture.md, the routers' access control:
:mod:`manus_stack.derived`); ``--check`` exits 1 when one of them is out of date.
"""

from __future__ import annotations

import argparse

from manus_stack.derived import stale
from schemas.export import write_schemas


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Output directory or check mode."""
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--out", metavar="DIR", help="directory to write the schemas into")
    group.add_argument("--check", action="store_true",
                       help="check the files derived from the endpoint table")  # fmt: skip
    group.add_argument("--update", action="store_true",
                       help="rewrite the files derived from the endpoint table")  # fmt: skip


def run(args: argparse.Namespace) -> int:
    """Write, check or update."""
    if args.check:
        old = stale()
        for path in old:
            print(f"{path} is out of date: run `manus schemas --update`")
        if not old:
            print("the files derived from the endpoint table are current")
        return 1 if old else 0
    if args.update:
        for path in stale(update=True):
            print(path)
        return 0
    for path in write_schemas(args.out):
        print(path)
    return 0
