"""The guardian's thin Zenoh shell, a process of its own: JSON lines on stdin -> reports.

``manus guardian`` starts it and writes one JSON object per action on its standard input;
this process publishes each as a :class:`schemas.guardian.GuardianReport` on
``<prefix>/guardian/report`` and holds the liveliness token ``alive/guardian``. When no
router answers it logs one warning and only drains its input, so the guardian never
blocks on a full pipe. It ends when its input closes.

With ``--disabled WHY`` (a guardian that stays off, ``manus guardian``) it holds the token
``disabled/guardian/<WHY>`` instead of ``alive/guardian`` and publishes nothing.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
from typing import Any

from manus.errors import ConfigError
from manus.node import Node, now_ns
from manus.session import add_bus_arguments, bus_settings
from schemas import endpoints as ep
from schemas.guardian import GuardianReport

log = logging.getLogger("manus.guardian.reporter")

FIELDS = ("syncs", "answered", "stops_sent", "late", "engaged")


def to_report(line: str, seq: int) -> GuardianReport | None:
    """The report of one input line (None, logged, if it is not one)."""
    try:
        obj: dict[str, Any] = json.loads(line)
        return GuardianReport(
            stamp_ns=now_ns(),
            seq=seq,
            action=obj["action"],
            sync_age_ms=float(obj["sync_age_ms"]),
            detail=str(obj.get("detail", "")),
            **{k: obj[k] for k in FIELDS},
        )
    except (ValueError, KeyError, TypeError) as exc:
        log.warning("not a guardian report: %r (%s)", line[:200], exc)
        return None


def main(argv: list[str] | None = None) -> int:
    """Publish the reports read on stdin until it closes."""
    parser = argparse.ArgumentParser(prog="python -m services.guardian.reporter")
    add_bus_arguments(parser)
    parser.add_argument(
        "--disabled", default="", help="hold disabled/guardian/<WHY> instead of reporting"
    )
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        # the where token names the guardian (this process's parent), not the reporter
        node: Node | None = Node(
            "guardian", bus_settings(args), pid=os.getppid(), liveliness=not args.disabled
        )
    except ConfigError as exc:
        log.warning("no report on Zenoh: %s", exc)
        node = None
    pub = None
    if node is not None and args.disabled:
        node.declare_disabled(args.disabled)
    elif node is not None:
        pub = node.publisher(node.keys(ep.GUARDIAN_REPORT))
    seq = 0
    try:
        for line in sys.stdin:
            report = to_report(line, seq) if pub is not None else None
            if pub is not None and report is not None:
                pub.put(report)
                seq += 1
    finally:
        if node is not None:
            node.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
