"""``manus demo drink``: the whole stack, the drink task, figures from the simulator's truth.

Writes the seeded setting (:class:`manus_stack.drink.DrinkSetting`: a cup on the table,
the user's mouth swaying and tracked with noise) into the run directory as the
simulator's objects and config files, brings the stack up (``manus up``'s processes),
then submits the panel's drink task (:data:`manus_stack.drink.TASK_FILE`): fold out, pick
the cup, bring it level toward the mouth, follow the mouth to the standoff and hold,
put the cup back where it was, home, fold in; with a progress bar. The user's "done"
(``manus task done``) ends the holding; the demo says it itself after ``--drink-s`` of
holding (0: it waits for yours, or the task's own timeout). While it runs the demo takes
the simulator's truth (``sim/truth``) and judges it (:class:`manus_stack.drink.
DrinkJudge`); then it stops the stack, prints the figures (time per phase, the arm's and
the cup's smallest distance to the person, contacts, the cup's largest tilt, the
placement error), writes a plot of them and prints ``recording: PATH`` and ``plot: PATH``.
Exits 0 when the drink succeeded on the truth, 1 otherwise (with the reason).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import sys
import threading
import time

from manus.node import Node, QueryError
from manus.process import wait_for_signal
from manus.session import client_settings
from manus_stack.commands.up import stack_options
from manus_stack.drink import TASK_FILE, DrinkJudge, DrinkSetting, plot, render
from manus_stack.up import LocalStack, StackError, StackOptions
from schemas import endpoints as ep
from schemas.sequencing import StepKind, TaskEvent, TaskEventKind
from schemas.state import SimTruth
from services.sequencer.client import TaskClient
from services.sequencer.progress import ProgressView
from services.sequencer.taskfile import load_task_file


def _setting(args: argparse.Namespace) -> tuple[DrinkSetting, StackOptions]:
    """The seeded setting, written into the run directory as the simulator's files."""
    setting = DrinkSetting.drawn(args.seed)
    options = stack_options(args)
    objects, sim_config = setting.write(options.run_dir)
    sim_args = [*options.sim_args, "--config", str(sim_config)]
    return setting, dataclasses.replace(options, objects=str(objects), sim_args=sim_args)


def run(args: argparse.Namespace) -> int:
    """Run the drink demo; see the module docstring."""
    stop = wait_for_signal()
    setting, options = _setting(args)
    judge = DrinkJudge(setting)
    lock = threading.Lock()
    stack = LocalStack(options)
    timers: list[threading.Timer] = []
    x, y, _ = setting.cup_xyz
    try:
        print(f"demo: starting the stack in {options.run_dir}", flush=True)
        print(f"demo: seed {setting.seed}, the cup at ({x * 1e3:.0f}, {y * 1e3:.0f}) mm")
        stack.start(timeout=args.start_timeout)
        settings = client_settings(options.endpoint, prefix=options.prefix)
        with Node("demo", settings, liveliness=False) as node:

            def on_truth(truth: SimTruth, rx_ns: int) -> None:
                with lock:
                    judge.on_truth(truth)

            node.subscribe(node.keys(ep.SIM_TRUTH), SimTruth, on_truth, locked=False)
            if not _drink(TaskClient(node), args, judge, lock, timers, stop):
                return 1
            time.sleep(1.0)  # the cup put back comes to rest; the recorder hears the end
    except StackError as exc:
        print(f"demo: {exc}", file=sys.stderr)
        return 1
    finally:
        for timer in timers:
            timer.cancel()
        codes = stack.stop()
        if codes:
            print("demo: stopped " + ", ".join(f"{k} {v}" for k, v in codes.items()), flush=True)
    with lock:
        figures = judge.figures()
    print(render(figures))
    if options.recording.exists():
        print(f"recording: {options.recording}")
    if judge.samples:
        out = plot(judge, options.run_dir / "demo_drink.png", f"manus demo drink, seed {args.seed}")
        print(f"plot: {out}")
    print(json.dumps(figures.row()))
    return 0 if figures.ok else 1


def _drink(
    client: TaskClient,
    args: argparse.Namespace,
    judge: DrinkJudge,
    lock: threading.Lock,
    timers: list[threading.Timer],
    stop: threading.Event,
) -> bool:
    """Submit the drink task and follow it to its end (False: refused)."""
    task = load_task_file(TASK_FILE)
    follow = next(i for i, s in enumerate(task.steps) if s.kind == StepKind.FOLLOW)
    client.wait_for_arm(args.start_timeout)
    time.sleep(2.0)  # the camera's first frames reach the world model
    try:
        reply = client.submit(task)
    except QueryError as exc:
        print(f"demo: {exc}", file=sys.stderr)
        return False
    if not reply.accepted:
        print("demo: task refused:\n  " + "\n  ".join(reply.errors), file=sys.stderr)
        return False
    task_id = reply.task_id
    print(f"demo: task {task_id}: {task.name}, {len(task.steps)} steps", flush=True)
    view = ProgressView(task, sys.stdout, live=sys.stdout.isatty() and not args.plain)

    def say_done() -> None:
        print("demo: the user says done", flush=True)
        with contextlib.suppress(QueryError):
            client.control("done", task_id)

    def on_event(event: TaskEvent) -> None:
        with lock:
            judge.on_event(event)
        holding = event.step == follow and event.event == TaskEventKind.STEP_PROGRESS
        if holding and not timers and args.drink_s > 0:
            timers.append(threading.Timer(args.drink_s, say_done))
            timers[0].start()
        view.show(event)

    final = client.follow(task_id, on_event, stop=stop, timeout=args.timeout)
    if final is None:
        with contextlib.suppress(QueryError):
            client.control("cancel", task_id)
        client.follow(task_id, on_event, timeout=10.0)
    return True
