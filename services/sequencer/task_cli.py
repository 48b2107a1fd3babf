"""``manus task ACTION [TASK_ID]``: pause, resume, cancel or show the running task; or
the recent tasks.

    manus task status
    manus task pause            # the current task; or give its id
    manus task resume
    manus task cancel
    manus task history          # the last 10 tasks, newest first (--limit N)

Prints the sequencer's TaskStatus (history: TaskHistory) as one JSON line; exits 0 when
the request was carried out, 1 when it was refused (the reason is in ``message``) or no
sequencer answered.
"""

from __future__ import annotations

import argparse
import json
import sys

from manus.errors import SchemaError
from manus.node import Node, QueryError
from manus.session import settings_from_env
from schemas.sequencing import TASK_ACTIONS
from services.sequencer.client import TaskClient

HISTORY = "history"
"""The action that lists the recent tasks (``sequencer/history``)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The action, the task and the bus settings."""
    parser.add_argument("action", choices=[*TASK_ACTIONS, HISTORY], help="what to do")
    parser.add_argument("--limit", type=int, default=10, help="history: how many (1..100)")
    parser.add_argument("task_id", nargs="?", default="", help="the task (default: current)")
    parser.add_argument("--connect", nargs="+", metavar="ENDPOINT", help="router endpoint(s)")
    parser.add_argument("--prefix", help="key prefix of the arm (default: manus)")


def run(args: argparse.Namespace) -> int:
    """Send the request and print the answer."""
    settings = settings_from_env(connect=args.connect, prefix=args.prefix)
    with Node("task", settings, liveliness=False) as node:
        try:
            if args.action == HISTORY:
                history = TaskClient(node).history(args.limit)
                sys.stdout.write(json.dumps(history.to_dict()) + "\n")
                return 0
            status = TaskClient(node).control(args.action, args.task_id)
        except (QueryError, SchemaError) as exc:
            sys.stderr.write(f"manus task: {exc}\n")
            return 1
    sys.stdout.write(json.dumps(status.to_dict()) + "\n")
    return 0 if status.ok else 1
