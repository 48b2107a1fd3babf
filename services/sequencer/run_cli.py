"""``manus run``: run a task, in the thesis form or from a TOML task file.

    manus run paths/thesis_square.txt 40 paths/thesis_circle.txt 0
    manus run task.toml

Waits up to ``--wait`` for the services, then submits the task to the running sequencer
(or, when none is up, runs one in this process): a bridge still starting (after
``manus up`` or a restart) holds the task in the sequencer until it runs, at most the
sequencer's ``bridge_wait_s`` (30 s by default); a bridge stopped (stopped, estopped,
arm_error) refuses it at once with the phase and its detail. Then it shows a progress
bar for the task and one for the current step, and exits 0 when the task succeeds; 1
with the failure reason when it fails or is cancelled, or when the sequencer's liveliness
token vanishes while the task runs and this client's link is up (the sequencer died or
hangs: no final event may come; named on stderr, within the token's loss); 2 when it is
refused. A final event lost on the way (a router restart, a sequencer whose session was
down) is read from ``sequencer/history`` once the sequencer's token is back, and said so
(every validation problem is printed, with its location). Ctrl-C cancels the task (the
arm decelerates and stops) and exits 130.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import threading

from manus.node import Node, QueryError
from manus.process import wait_for_signal
from manus.session import settings_from_env
from schemas.sequencing import StepKind, Task, TaskAction, TaskEvent, TaskEventKind, TaskStep
from services.sequencer.client import LINK_WAIT_S, TaskClient
from services.sequencer.config import REQUIRED_SERVICES
from services.sequencer.progress import ProgressView
from services.sequencer.shell import SequencerShell
from services.sequencer.taskfile import TaskFileError, load_task_file, task_from_args


def _out(text: str) -> None:
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


def _err(text: str) -> None:
    sys.stderr.write(text + "\n")
    sys.stderr.flush()


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The task and the bus settings."""
    parser.add_argument(
        "task",
        nargs="+",
        metavar="ITEM",
        help="a .toml task file, or via-point files and gripper openings [mm], alternating",
    )
    parser.add_argument(
        "--mode",
        dest="control_mode",
        choices=("default", "thesis"),
        help="controller mode of the move steps (default: default)",
    )
    parser.add_argument(
        "--fold-out", action="store_true", help="unfold the arm before the steps (thesis form)"
    )
    parser.add_argument(
        "--fold-in", action="store_true", help="fold the arm after the steps (thesis form)"
    )
    add_bus_arguments(parser)


def add_bus_arguments(parser: argparse.ArgumentParser) -> None:
    """Where the stack is and how to follow a task (``manus run``, ``manus reach``)."""
    parser.add_argument("--connect", nargs="+", metavar="ENDPOINT", help="router endpoint(s)")
    parser.add_argument("--prefix", help="key prefix of the arm (default: manus)")
    parser.add_argument(
        "--wait",
        type=float,
        default=10.0,
        metavar="S",
        help="how long to wait for the services to come up [s]",
    )
    parser.add_argument(
        "--timeout",
        type=float,
        default=None,
        metavar="S",
        help="give up (and cancel) after this long [s]",
    )
    parser.add_argument(
        "--plain", action="store_true", help="one line per event instead of redrawn progress bars"
    )


def load_task(items: list[str], mode: str | None) -> Task:
    """The task of the command line: one ``.toml`` file, or the thesis form."""
    if len(items) == 1 and items[0].endswith(".toml"):
        task = load_task_file(items[0])
        if mode is not None:
            task = Task(steps=task.steps, name=task.name, mode=mode)
        return task
    return task_from_args(items, mode=mode or "default")


def with_folds(task: Task, fold_out: bool, fold_in: bool) -> Task:
    """``task`` with a fold_out step first and/or a fold_in step last."""
    steps = list(task.steps)
    if fold_out:
        steps.insert(0, TaskStep(kind=StepKind.FOLD_OUT, where="--fold-out"))
    if fold_in:
        steps.append(TaskStep(kind=StepKind.FOLD_IN, where="--fold-in"))
    return Task(steps=steps, name=task.name, mode=task.mode)


def run(args: argparse.Namespace) -> int:
    """Run the task; see the module docstring for exit codes."""
    try:
        task = with_folds(load_task(args.task, args.control_mode), args.fold_out, args.fold_in)
    except TaskFileError as exc:
        _err("manus run: task refused:\n  " + "\n  ".join(exc.errors))
        return 2
    return submit_and_follow(task, args)


def submit_and_follow(task: Task, args: argparse.Namespace, command: str = "manus run") -> int:
    """Submit ``task`` to the stack (``args``: :func:`add_bus_arguments`) and follow it to
    its end; the exit status of the module docstring, messages starting ``command:``."""
    settings = settings_from_env(connect=args.connect, prefix=args.prefix)
    stop = wait_for_signal()
    with contextlib.ExitStack() as stack:
        node = stack.enter_context(Node("run", settings, liveliness=False))
        client = TaskClient(node)
        if "sequencer" not in node.alive_services(timeout=1.0):
            _err(f"{command}: no sequencer is running: running one in this process")
            stack.enter_context(SequencerShell(settings, session=node.session))
        missing = client.wait_for_services((*REQUIRED_SERVICES, "sequencer"), args.wait)
        if missing:
            _err(
                f"{command}: waited {args.wait:g} s; still missing: {', '.join(missing)} "
                "(start them, e.g. with `manus up`)"
            )
        elif client.bridge_phase != "running":  # the sequencer holds the task meanwhile
            _err(
                f"{command}: the bridge is not running yet (phase "
                f"{client.bridge_phase or 'unknown'}): the sequencer waits for it (its "
                "bridge_wait_s, 30 s by default) or refuses the task at once if it stopped"
            )
        try:
            reply = client.submit(task)
        except QueryError as exc:
            _err(f"{command}: {exc}")
            return 1
        if not reply.accepted:
            _err(f"{command}: task refused:\n  " + "\n  ".join(reply.errors))
            return 2
        _out(f"task {reply.task_id}: {task.name} ({len(task.steps)} steps)")
        view = ProgressView(task, sys.stdout, live=sys.stdout.isatty() and not args.plain)
        final = client.follow(reply.task_id, view.show, stop=stop, timeout=args.timeout)
        return _outcome(client, reply.task_id, final, view, stop, args.timeout, command)


def _outcome(
    client: TaskClient,
    task_id: str,
    final: TaskEvent | None,
    view: ProgressView,
    stop: threading.Event,
    timeout: float | None,
    command: str,
) -> int:
    """The exit status of a followed task (cancelling it when interrupted or too long)."""
    if final is None and client.sequencer_gone.is_set():
        _err(
            f"{command}: the sequencer is gone (its liveliness token alive/sequencer "
            f"vanished: it died or hangs) while task {task_id} ran: its outcome is "
            "unknown; the controller's deadman stops the arm"
        )
        return 1
    if final is None and client.link_lost:
        _err(
            f"{command}: no link to the router for {LINK_WAIT_S:g} s while task {task_id} "
            "ran: its outcome is unknown (`manus task history` tells it once the link is back)"
        )
        return 1
    if final is not None and final is client.recovered:
        _err(
            f"{command}: the final event of task {task_id} was lost on the way (a link or "
            "the sequencer's session was down): read from sequencer/history"
        )
    if final is None:
        why = "interrupted" if stop.is_set() else f"no end within {timeout:g} s"
        _err(f"{command}: {why}: cancelling task {task_id}")
        with contextlib.suppress(QueryError):
            client.control(TaskAction.CANCEL, task_id)
        client.follow(task_id, view.show, timeout=10.0)
        return 130 if stop.is_set() else 1
    if final.event != TaskEventKind.SUCCEEDED:
        _err(f"{command}: task {final.event}: {final.reason}")
        return 1
    _out(f"task {task_id}: succeeded")
    return 0
