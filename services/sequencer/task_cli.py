"""``manus task ACTION [TASK_ID]``: pause, resume, cancel or show the running task.

    manus task status
    manus task pause            # the current task; or give its id
    manus task resume
    manus task cancel

Prints the sequencer's TaskStatus as one JSON line; exits 0 when the request was carried
out, 1 when it was refused (the reason is in ``message``) or no sequencer answered.
"""

from __future__ import annotations

import argparse
import json
import sys

from manus.node import Node, QueryError
from manus.session import settings_from_env
from schemas.sequencing import TASK_ACTIONS
from services.sequencer.client import TaskClient


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The action, the task and the bus settings."""
    parser.add_argument("action", choices=TASK_ACTIONS, help="what to do")
    parser.add_argument("task_id", nargs="?", default="", help="the task (default: current)")
    parser.add_argument("--connect", nargs="+", metavar="ENDPOINT", help="router endpoint(s)")
    parser.add_argument("--prefix", help="key prefix of the arm (default: manus)")


def run(args: argparse.Namespace) -> int:
    """Send the request and print the answer."""
    settings = settings_from_env(connect=args.connect, prefix=args.prefix)
    with Node("task", settings, liveliness=False) as node:
        try:
            status = TaskClient(node).control(args.action, args.task_id)
        except QueryError as exc:
            sys.stderr.write(f"manus task: {exc}\n")
            return 1
    sys.stdout.write(json.dumps(status.to_dict()) + "\n")
    return 0 if status.ok else 1
