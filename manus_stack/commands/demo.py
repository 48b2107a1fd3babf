"""``manus demo [square|circle|drink]``: the whole stack, the thesis path, a report
(``drink``: the drink task judged on the simulator's truth, :mod:`.demo_drink`).

Brings the stack up (``manus up``'s processes: router, simulator, bridge, planner,
controller, sequencer, recorder), then runs one task through the sequencer: fold out,
the thesis path in real time, close and open the gripper, fold in; with a progress bar.
Then stops the stack (the recording is closed), prints the via-point errors (mean, max,
per via point) next to the thesis's figures, writes a PNG (planned vs executed path in
the yz plane, error over time), and prints ``recording: PATH`` and ``plot: PATH`` (and
``overview: PATH``, the recorder's four-panel plot read back from the recording).
Exits 0 when the task succeeded, 1 otherwise (with the reason).

When ``manus record`` is not installed the demo records the bus itself (same MCAP
format, ``services.recorder.writer``).
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from pathlib import Path

from manus.config import load_arm_config
from manus.node import Node, QueryError
from manus.process import wait_for_signal
from manus.session import client_settings
from manus_stack.commands.up import add_stack_arguments, stack_options
from manus_stack.demo import (
    THESIS_MAX_MM,
    THESIS_MEAN_MM,
    Collected,
    demo_task,
    error_table,
    plot_run,
)
from manus_stack.up import LocalStack, StackError
from schemas.sequencing import TaskEvent
from services.sequencer.client import TaskClient
from services.sequencer.progress import ProgressView


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The shape and the stack options."""
    parser.add_argument(
        "shape",
        nargs="?",
        default="square",
        choices=("square", "circle", "drink"),
        help="the thesis path to run (default: square), or drink: the cup from the table to "
        "the user's mouth and back (docs/drink.md)",
    )
    add_stack_arguments(parser)
    parser.add_argument(
        "--timeout",
        type=float,
        default=180.0,
        metavar="S",
        help="give up on the task after this long [s]",
    )
    parser.add_argument("--plain", action="store_true", help="one line per task event")
    parser.add_argument(
        "--seed", type=int, default=0, help="drink: the setting's seed (the cup's place, noise)"
    )
    parser.add_argument(
        "--drink-s",
        type=float,
        default=5.0,
        metavar="S",
        help="drink: say done after holding at the mouth this long [s] (0: wait for "
        "`manus task done` or the task's own timeout)",
    )


def run(args: argparse.Namespace) -> int:
    """Run the demo; see the module docstring."""
    if args.shape == "drink":
        from manus_stack.commands import demo_drink

        return demo_drink.run(args)
    stop = wait_for_signal()
    options = stack_options(args)
    task = demo_task(args.shape)
    stack = LocalStack(options)
    collected = Collected()
    recording = options.recording
    final: TaskEvent | None = None
    task_id = ""
    try:
        print(f"demo: starting the stack in {options.run_dir}", flush=True)
        stack.start(timeout=args.start_timeout)
        for line in stack.describe():
            print(f"  {line}")
        settings = client_settings(options.endpoint, prefix=options.prefix)
        with Node("demo", settings, liveliness=False) as node:
            collected.listen(node)
            client = TaskClient(node)
            phase = client.wait_for_arm(args.start_timeout)
            print(f"demo: bridge phase {phase or 'unknown'}", flush=True)
            try:
                reply = client.submit(task)
            except QueryError as exc:
                print(f"demo: {exc}", file=sys.stderr)
                return 1
            if not reply.accepted:
                print("demo: task refused:\n  " + "\n  ".join(reply.errors), file=sys.stderr)
                return 1
            task_id = reply.task_id
            print(f"demo: task {task_id}: {task.name}, {len(task.steps)} steps", flush=True)
            view = ProgressView(task, sys.stdout, live=sys.stdout.isatty() and not args.plain)
            final = client.follow(task_id, view.show, stop=stop, timeout=args.timeout)
            if final is None:
                with contextlib.suppress(QueryError):
                    client.control("cancel", task_id)
                client.follow(task_id, view.show, timeout=10.0)
            time.sleep(0.3)  # the last results and feedback reach the recorder too
    except StackError as exc:
        print(f"demo: {exc}", file=sys.stderr)
        return 1
    finally:
        codes = stack.stop()
        if codes:
            print("demo: stopped " + ", ".join(f"{k} {v}" for k, v in codes.items()), flush=True)
    return _report(args.shape, collected, task_id, final, recording, options.run_dir)


def _overview(recording: Path, out: Path, title: str) -> None:
    """The recorder's four-panel plot of the whole recording (``manus plot``), read back
    from the MCAP: path, joints, increments, via-point table."""
    from services.recorder.errors import RecordingError
    from services.recorder.plot import plot_recording

    try:
        summary = plot_recording(recording, out, arm=load_arm_config(), title=title)
    except RecordingError as exc:
        print(f"demo: cannot plot the recording: {exc}", file=sys.stderr)
        return
    print(
        f"overview: {summary.output} (from the recording: {summary.goals} path(s), "
        f"mean {summary.mean_mm:.2f} mm, max {summary.max_mm:.2f} mm)"
    )
    if summary.clearance is not None:
        print(f"clearances (simulator's truth): {summary.clearance_verdict}")


def _report(
    shape: str,
    collected: Collected,
    task_id: str,
    final: TaskEvent | None,
    recording: Path,
    run_dir: Path,
) -> int:
    """Print the error table, write the plot, print where things are; the exit status."""
    result = collected.path_result(task_id) if task_id else None
    plot = run_dir / f"demo_{shape}.png"
    if result is not None:
        goal = collected.goals.get(result.goal_id)
        table = error_table(result, goal)
        title = (
            f"via-point errors of the thesis {shape} ({result.status}; gripper position "
            "at each via point's time, FK of the encoders):"
        )
        print(table.render(title))
        feedback = collected.feedback_of(result.goal_id)
        plot_run(
            feedback,
            goal,
            plot,
            f"manus demo {shape}: mean {table.mean_mm:.2f} mm, max {table.max_mm:.2f} mm "
            f"at the via points (thesis: {THESIS_MEAN_MM:g} / ~{THESIS_MAX_MM:g} mm)",
        )
    else:
        print("demo: no trajectory result was heard: no error table, no plot", file=sys.stderr)
    if recording.exists():
        print(f"recording: {recording}")
        _overview(recording, run_dir / "overview.png", f"manus demo {shape}")
    if result is not None:
        print(f"plot: {plot}")
    if final is None:
        print("demo: the task did not end (interrupted or timed out)", file=sys.stderr)
        return 1
    if final.event != "succeeded":
        print(f"demo: task {final.event}: {final.reason}", file=sys.stderr)
        return 1
    print(f"demo: task {task_id} succeeded", flush=True)
    return 0
