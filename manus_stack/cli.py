"""The ``manus`` command: one subcommand per job, each implemented in its own module.

Each command module defines ``add_arguments(parser)`` and ``run(args) -> int``; it is
imported only when its subcommand runs, so ``manus kin`` does not pay for Zenoh or
Pinocchio.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys

from manus.errors import ManusError

COMMANDS: dict[str, tuple[str, str]] = {
    "kin": ("manus_stack.commands.kin", "kinematics: fk, ik, jacobian, urdf"),
    "bench": ("manus_stack.commands.bench", "benchmarks; prints figures as JSON"),
    "sim": ("services.simulator.main", "the Manus simulator (a python-can peer)"),
    "bridge": ("services.can_bridge.main", "the CAN bridge: owns the bus and the 60 ms cycle"),
    "guardian": ("services.guardian.main", "stop the arm when a sync goes unanswered (CAN only)"),
    "planner": ("services.planner.main", "the planner service: via points -> joint trajectories"),
    "plan": (
        "manus_stack.commands.plan",
        "plan a via-point file or a goal; prints the trajectory as JSON",
    ),
    "controller": ("services.controller.main", "the controller service: tracking, gripper loop"),
    "sequencer": ("services.sequencer.main", "the sequencer service: tasks, the supervisor API"),
    "run": ("services.sequencer.run_cli", "run a task: PATH.txt MM PATH.txt ... or TASK.toml"),
    "reach": ("manus_stack.commands.reach", "move to a goal (pose, joints, named, object, line)"),
    "move-to": ("manus_stack.commands.move_to", "move to a named pose (home, drink, ...)"),
    "pick": ("manus_stack.commands.pick", "pick an object of the world model up (e.g. cup)"),
    "place": (
        "manus_stack.commands.place",
        "put the held object down --at a pose or --on a surface",
    ),
    "give": ("manus_stack.commands.give", "hand the held object to the user"),
    "jog": ("manus_stack.commands.jog", "drive the arm from the keyboard (live control)"),
    "panel": ("manus_stack.commands.panel", "the web page for the user: tasks, jog pad, STOP"),
    "track": ("manus_stack.commands.track", "follow a tracker's target (a mouth) to a standoff"),
    "task": ("services.sequencer.task_cli", "pause, resume, cancel or show the running task"),
    "schemas": ("manus_stack.commands.schemas", "write the JSON Schema of every bus message"),
    "router": ("manus_stack.commands.router", "a Zenoh router on loopback (Python, no zenohd)"),
    "certs": ("manus_stack.commands.certs", "lab CA, router certificates, Zenoh passwords"),
    "up": ("manus_stack.commands.up", "start the whole stack locally until Ctrl-C"),
    "status": ("manus_stack.commands.status", "services alive and where, bridge health, arm"),
    "demo": ("manus_stack.commands.demo", "the stack, the thesis path, an error table and a plot"),
    "record": ("services.recorder.main", "record the bus to MCAP (or --recover a crashed file)"),
    "replay": ("manus_stack.commands.replay", "replay an MCAP onto the bus, or --check a core"),
    "playback": ("services.recorder.playback_cli", "pause, resume, step, seek or rate a replay"),
    "export": ("manus_stack.commands.export", "MCAP -> JSON MCAP (Foxglove), candump .log, info"),
    "view": ("services.viewer.main", "the arm live in Foxglove (WebSocket server, 127.0.0.1:8765)"),
    "plot": ("services.recorder.plot_cli", "plot a recording: yz path, joints, increments, errors"),
    "scene": ("manus_stack.commands.scene", "draw the arm in its scene, or check a scene file"),
}
"""Subcommand -> (module, one-line help)."""


def build_parser(selected: str | None = None) -> argparse.ArgumentParser:
    """The parser; only ``selected``'s module is imported to declare its arguments."""
    parser = argparse.ArgumentParser(
        prog="manus",
        description="Control stack for the Manus assistive robot arm.",
    )
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        if name == selected:
            importlib.import_module(module).add_arguments(p)
    return parser


BROKEN_PIPE_EXIT = 128 + 13
"""Exit status when the reader of standard output went away (as if SIGPIPE had ended
the process, which Python ignores)."""


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``manus`` console script.

    A reader of standard output that goes away early (``manus kin ik ... | head``) ends the
    command quietly with :data:`BROKEN_PIPE_EXIT`, whichever command was printing.
    """
    try:
        try:
            status = _run(argv)
        finally:  # also after argparse's SystemExit (--help, usage errors)
            sys.stdout.flush()  # here, not at exit, so that a closed pipe is caught below
    except BrokenPipeError:
        # Nothing more can reach the reader: point standard output at /dev/null so that
        # the interpreter's own flush at exit does not fail again.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
        return BROKEN_PIPE_EXIT
    return status


def _run(argv: list[str] | None) -> int:
    """Parse ``argv`` and run the selected command; its exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    selected = next((a for a in argv if a in COMMANDS), None)
    parser = build_parser(selected)
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    module = importlib.import_module(COMMANDS[args.command][0])
    try:
        return int(module.run(args))
    except ManusError as exc:
        print(f"manus {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
