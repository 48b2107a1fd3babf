"""``manus up``: the whole stack on this machine, each service its own process.

    manus up                                   # simulator (slcan on 127.0.0.1), the rest, recorder
    manus up --sim-link pty                    # the simulator's slcan on pseudo-terminals
    manus up --can-interface socketcan --can-channel can0    # a real arm instead
    manus up --can-interface slcan --can-channel /dev/ttyACM0 \
        --guardian-channel /dev/ttyACM1          # slcan: the guardian on a second adapter
    manus up --endpoint tcp/127.0.0.1:7500 --prefix arm2     # a second stack alongside
    manus up --view                            # and the arm live in Foxglove (port 8765)

Starts a loopback Zenoh router, the simulator (or nothing, with a real arm; its camera
reports its objects, ``--objects``), the bridge,
the CAN guardian (not with ``--no-guardian``), planner, controller, sequencer and
recorder (``manus_stack.up``), waits until each one's liveliness token is up and the
bridge is in phase ``running`` (the arm powered up, in joint mode, its start-up moves
done), then prints where things are and ``up: ...``, and runs until Ctrl-C (or
``--duration``), then stops every process it started, newest first, by pid. All of that
within ``--start-timeout`` (default 60 s); else it exits 1 saying what did not come up:
a process and its log, or the bridge's phase and its detail (at once for a phase the
bridge does not leave by itself: stopped, estopped, arm_error). Exits 1 as well when a
process dies meanwhile.

The guardian never shares a single-reader CAN channel (slcan, serial) with the bridge
(``manus_stack.guardian_can``): give it its own, a second adapter on the same bus
(``--guardian-channel``; ``--guardian-interface`` if of another kind). Without one it
stays off, ``manus up`` says so and why (``guardian: OFF: ...``) and ``manus status``
shows it; a ``--guardian-channel`` that is the bridge's own is refused before anything
starts. socketcan and the other shared interfaces keep one channel for both.
"""

from __future__ import annotations

import argparse
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

from manus.process import wait_for_signal
from manus.realtime import Priority
from manus_stack.up import LocalStack, StackOptions
from services.simulator.nodes import LINKS


def add_stack_arguments(parser: argparse.ArgumentParser) -> None:
    """Options shared by ``manus up`` and ``manus demo``."""
    parser.add_argument(
        "--endpoint",
        default="tcp/127.0.0.1:7447",
        help="loopback endpoint of the router (default tcp/127.0.0.1:7447)",
    )
    parser.add_argument("--prefix", default="manus", help="key prefix of the arm")
    parser.add_argument("--run-dir", help="logs, recording (default runs/<UTC time>)")
    parser.add_argument(
        "--can-interface",
        default="",
        help="python-can interface of a real arm (default: the simulator)",
    )
    parser.add_argument("--can-channel", default="", help="its channel (e.g. can0)")
    parser.add_argument(
        "--objects",
        default="default",
        help="the simulator's objects, which its camera reports: 'default' (a cup, a bottle "
        "and a phone on the table), 'none' or an objects file (docs/objects.md)",
    )
    parser.add_argument(
        "--sim-link",
        choices=LINKS,
        default="tcp",
        help="how the bridge and the guardian reach the simulator's slcan adapters: TCP on "
        "127.0.0.1 (default: under CPU load a pty's bytes wait in a kernel worker, "
        "docs/simulator.md, Links) or pseudo-terminals, as a USB adapter's serial device",
    )
    parser.add_argument(
        "--guardian-channel",
        default="",
        help="the guardian's own channel, a second adapter on the arm's bus (needed with "
        "slcan or serial; default: the bridge's if it can be shared, as with socketcan)",
    )
    parser.add_argument(
        "--guardian-interface", default="", help="its interface (default: --can-interface)"
    )
    parser.add_argument(
        "--no-record",
        dest="record",
        action="store_false",
        help="do not start the recorder (nor the flight recorder)",
    )
    parser.add_argument(
        "--no-guardian",
        dest="guardian",
        action="store_false",
        help="do not start the CAN guardian beside the bridge",
    )
    parser.add_argument(
        "--ring",
        type=float,
        default=30.0,
        metavar="S",
        help="seconds the flight recorder keeps (files under <run dir>/flight; 0: none)",
    )
    parser.add_argument(
        "--view", action="store_true", help="also serve the arm to Foxglove (manus view)"
    )
    parser.add_argument("--view-port", type=int, default=8765, help="manus view's port")
    parser.add_argument(
        "--realtime",
        default="",
        metavar="POLICY",
        help="scheduling of the services on the 60 ms path (router, simulator, bridge, "
        "guardian, controller, sequencer): off, rr[:PRIO], fifo[:PRIO], nice[:N] "
        "(default: $MANUS_REALTIME, else rr:20 on the CAN bus, rr:10 the rest; "
        "docs/deployment.md)",
    )
    parser.add_argument(
        "--start-timeout",
        type=float,
        default=60.0,
        metavar="S",
        help="how long to wait for every service and the bridge's phase running [s] (default 60)",
    )


def stack_options(args: argparse.Namespace) -> StackOptions:
    """:class:`StackOptions` of the shared arguments."""
    stamp = datetime.now(UTC).strftime("%Y%m%d-%H%M%S")
    run_dir = Path(args.run_dir) if args.run_dir else Path("runs") / stamp
    return StackOptions(
        run_dir=run_dir.resolve(),
        endpoint=args.endpoint,
        prefix=args.prefix,
        can_interface=args.can_interface,
        can_channel=args.can_channel,
        guardian_interface=args.guardian_interface,
        guardian_channel=args.guardian_channel,
        record=args.record,
        guardian=args.guardian,
        flight_ring_s=max(0.0, args.ring),
        view=args.view,
        view_port=args.view_port,
        objects=args.objects,
        realtime=str(Priority.parse(args.realtime)) if args.realtime else "",
        sim_args=["--link", args.sim_link],
    )


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Stack options and how long to run."""
    add_stack_arguments(parser)
    parser.add_argument(
        "--duration", type=float, metavar="S", help="stop after this long [s] (default: at Ctrl-C)"
    )


def run(args: argparse.Namespace) -> int:
    """Bring the stack up, wait, bring it down."""
    stop = wait_for_signal()
    stack = LocalStack(stack_options(args))
    try:
        start = time.monotonic()
        stack.start(timeout=args.start_timeout)
        stack.wait_running(max(0.0, args.start_timeout - (time.monotonic() - start)))
        for line in stack.describe():
            print(line)
        print(
            "up: every service is alive, the bridge is running; Ctrl-C stops them all", flush=True
        )
        deadline = None if args.duration is None else time.monotonic() + args.duration
        while not stop.is_set():
            if deadline is not None and time.monotonic() >= deadline:
                break
            dead = stack.exited()
            if dead:
                for child in dead:
                    print(
                        f"up: manus {child.name} exited with status {child.proc.returncode} "
                        f"(log {child.log})",
                        file=sys.stderr,
                    )
                return 1
            stop.wait(0.2)
        return 0
    finally:
        codes = stack.stop()
        if codes:
            print("down: " + ", ".join(f"{k} {v}" for k, v in codes.items()), flush=True)
