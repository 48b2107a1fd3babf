"""``manus guardian``: stop the arm when no other node answers a sync (see ``core.py``).

    manus guardian                                            # the simulator's second node
    manus guardian --can-interface socketcan --can-channel can0   # beside the bridge on a real arm
    manus guardian --can-interface slcan --can-channel /dev/ttyACM1 \
        --bridge-channel /dev/ttyACM0                         # its own adapter on the arm's bus

An independent process with its own CAN connection: it imports :mod:`manus.protocol`,
:mod:`manus.canbus`, :mod:`manus.can_sharing` and :mod:`manus.realtime` (Zenoh-free),
python-can and the standard library only (no Zenoh, nothing of the bridge or the controller). With
``slcan`` and no ``--can-channel`` the channel is read from ``--device-file``
(``manus sim --nodes 2`` writes node 1's channel to ``<its --device-file>.1``; default
``$MANUS_SIM_DEVICE_FILE.1`` or ``/tmp/manus-sim.device.1``).

It never shares a single-reader channel with the bridge (:mod:`manus.can_sharing`: two
readers of one serial line split its bytes): given the bridge's channel
(``--bridge-channel``) and the same one of an interface such as slcan, it stays **off**:
it opens nothing, says why on standard error, and its reporter holds the token
``disabled/guardian/single_reader_channel`` (``manus status`` shows it) until it is stopped.
A single-reader channel it does open is locked first, so a guardian pointed at the
bridge's device by another name is refused with an error naming the device.

Each action is logged on standard error; unless
``--no-report``, a reporter process (``python -m services.guardian.reporter``, the only
part that speaks Zenoh) publishes it on ``<prefix>/guardian/report``. It is fed through a
pipe by a thread with a bounded queue, so the decision never waits on it: when the queue
is full, reports are dropped and counted. Prints ``guardian: ...`` when ready and a
``stats:`` JSON line on exit (SIGINT/SIGTERM or ``--duration``).
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from dataclasses import asdict
from pathlib import Path
from types import FrameType
from typing import IO, Any

import can

from manus.can_sharing import DISABLED_SINGLE_READER, claim_channel, second_reader_refusal
from manus.canbus import open_bus, settles_at_once
from manus.errors import ConfigError
from manus.protocol import BITRATE
from manus.realtime import CAN_EDGE, add_realtime_argument, raise_priority, setting
from services.guardian.core import DEFAULT_DEADLINE_MS, Action, GuardianCore
from services.guardian.loop import LoopStats, run_loop

log = logging.getLogger("manus.guardian")

QUEUE_SIZE = 256
"""Reports waiting for the reporter; more are dropped (and counted)."""
COUNTS_EVERY_S = 1.0
"""The running counts are reported this often [s]."""


def default_device_file() -> str:
    """Node 1 of ``manus sim --nodes 2`` (the bridge is node 0)."""
    return os.environ.get("MANUS_SIM_DEVICE_FILE", "/tmp/manus-sim.device") + ".1"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``manus guardian``."""
    parser.add_argument("--can-interface", default="slcan", help="python-can interface")
    parser.add_argument(
        "--can-channel",
        default="",
        help="channel (can0, /dev/ttyACM1, socket://127.0.0.1:PORT ...)",
    )
    parser.add_argument("--bitrate", type=int, default=BITRATE, help="bit/s (default 250000)")
    parser.add_argument(
        "--device-file",
        default=default_device_file(),
        help="with slcan and no --can-channel: file holding the simulator node's channel",
    )
    parser.add_argument("--wait-device", type=float, default=10.0, help="wait for it [s]")
    parser.add_argument(
        "--bridge-channel",
        default="",
        help="the bridge's channel: with a single-reader interface (slcan, serial) the "
        "guardian does not open it too, and stays off saying why",
    )
    parser.add_argument(
        "--bridge-interface", default="", help="the bridge's interface (default: the same)"
    )
    parser.add_argument(
        "--deadline-ms",
        type=float,
        default=DEFAULT_DEADLINE_MS,
        help="stop the arm when no reply came this long after a sync (default 12 ms)",
    )
    parser.add_argument(
        "--report",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="publish actions on <prefix>/guardian/report through a reporter process",
    )
    parser.add_argument("--connect", nargs="+", metavar="ENDPOINT", help="router (reporter)")
    parser.add_argument("--prefix", help="key prefix (reporter; default $MANUS_PREFIX)")
    parser.add_argument("--duration", type=float, help="stop after this many seconds")
    add_realtime_argument(parser, CAN_EDGE)


def guardian_channel(args: argparse.Namespace) -> str:
    """The guardian's channel: as given, or (slcan without one) read from the device file.

    Raises:
        SystemExit: no channel and no device file within ``--wait-device``.
    """
    if args.can_channel or args.can_interface != "slcan":
        return str(args.can_channel)
    path, deadline = Path(args.device_file), time.monotonic() + args.wait_device
    while not path.exists():
        if time.monotonic() >= deadline:
            raise SystemExit(f"manus guardian: no device file {path}: give --can-channel")
        time.sleep(0.05)
    return path.read_text().strip()


def open_guardian_bus(args: argparse.Namespace, channel: str) -> can.BusABC:
    """The guardian's own CAN connection on ``channel`` (its device locked first:
    :func:`manus.can_sharing.claim_channel`; the lock goes with the process)."""
    extra = dict[str, Any]()
    if args.can_interface == "slcan":
        # non-blocking serial reads: the loop waits in select (services.guardian.loop)
        extra = {"timeout": 0, "sleep_after_open": 0 if settles_at_once(channel) else 2}
    try:
        claim_channel(args.can_interface, channel, "manus guardian")
        return open_bus(args.can_interface, channel, args.bitrate, **extra)
    except ConfigError as exc:
        raise SystemExit(str(exc)) from exc


class Reports:
    """Actions -> a bounded queue -> a thread writing JSON lines to the reporter's stdin."""

    def __init__(self, core: GuardianCore, sink: IO[str] | None) -> None:
        self.core = core
        self.dropped = 0
        self._queue: queue.Queue[dict[str, Any]] = queue.Queue(QUEUE_SIZE)
        self._sink = sink
        if sink is not None:
            threading.Thread(target=self._drain, name="guardian-report", daemon=True).start()

    def __call__(self, action: Action) -> None:
        age_ms = (action.t_ns - action.sync_ns) / 1e6
        level = logging.INFO if action.kind == "bridge_back" else logging.WARNING
        log.log(level, "%s (sync %.1f ms ago) %s", action.kind, age_ms, self.core.counts)
        self.put(action.kind, age_ms)

    def put(self, kind: str, age_ms: float = 0.0, detail: str = "") -> None:
        """Queue one report (dropped and counted when the queue is full)."""
        if self._sink is None:
            return
        report = {"action": kind, "sync_age_ms": round(max(0.0, age_ms), 3), "detail": detail}
        report |= {**asdict(self.core.counts), "engaged": self.core.engaged}
        try:
            self._queue.put_nowait(report)
        except queue.Full:
            self.dropped += 1

    def _drain(self) -> None:
        assert self._sink is not None
        while True:
            report = self._queue.get()
            try:
                self._sink.write(json.dumps(report) + "\n")
                self._sink.flush()
            except (OSError, ValueError):
                return  # the reporter is gone: the guardian goes on without it


def start_reporter(args: argparse.Namespace, disabled: str = "") -> subprocess.Popen[str]:
    """The reporter process, fed on its stdin (it exits when the pipe closes); with
    ``disabled``, it holds ``disabled/guardian/<disabled>`` instead of reporting."""
    cmd = [sys.executable, "-m", "services.guardian.reporter"]
    cmd += ["--connect", *args.connect] if args.connect else []
    cmd += ["--prefix", args.prefix] if args.prefix else []
    cmd += ["--disabled", disabled] if disabled else []
    return subprocess.Popen(cmd, stdin=subprocess.PIPE, text=True)


def stay_off(args: argparse.Namespace, stop: threading.Event, why: str) -> int:
    """Open nothing; say ``why`` and hold the ``disabled`` token (reporter) until stopped."""
    print(f"guardian: off: {why}", file=sys.stderr, flush=True)
    reporter = start_reporter(args, disabled=DISABLED_SINGLE_READER) if args.report else None
    stop.wait(args.duration)
    if reporter is not None:
        stop_reporter(reporter)
    return 0


def stop_reporter(reporter: subprocess.Popen[str]) -> None:
    """Close the reporter's input and wait for it (killed after 2 s)."""
    if reporter.stdin is not None:
        reporter.stdin.close()
    try:
        reporter.wait(2.0)
    except subprocess.TimeoutExpired:
        reporter.kill()


def run(args: argparse.Namespace) -> int:
    """Guard the bus until interrupted."""
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    priority = setting(args, default=CAN_EDGE)
    channel = guardian_channel(args)
    bridge_interface = args.bridge_interface or args.can_interface
    why = second_reader_refusal(args.can_interface, channel, bridge_interface, args.bridge_channel)
    if why:
        return stay_off(args, stop, why)
    core = GuardianCore(args.deadline_ms)
    bus = open_guardian_bus(args, channel)
    reporter = start_reporter(args) if args.report else None
    reports = Reports(core, reporter.stdin if reporter is not None else None)
    stats = LoopStats()
    loop = threading.Thread(
        target=run_loop, args=(bus, core, stop, reports), kwargs={"stats": stats}, daemon=True
    )
    try:
        loop.start()
        raise_priority(priority, "manus guardian")  # after the reporter started: not it
        where = f"{args.can_interface} {channel}, deadline {args.deadline_ms:g} ms"
        reports.put("started", detail=where)
        print(f"guardian: {where}", file=sys.stderr, flush=True)
        end = math.inf if args.duration is None else time.monotonic() + args.duration
        while not stop.wait(max(0.0, min(COUNTS_EVERY_S, end - time.monotonic()))):
            if time.monotonic() >= end:
                stop.set()
                break
            reports.put("counts")
        loop.join(1.0)
        reports.put("stopped")
    finally:
        bus.shutdown()
        if reporter is not None:
            time.sleep(0.1)  # let the last reports leave
            stop_reporter(reporter)
    reaction = sorted(stats.reaction_ms)
    out = {
        **asdict(core.counts),
        "reports_dropped": reports.dropped,
        "send_errors": stats.send_errors,
        "recv_errors": stats.recv_errors,
        "cpu_ms": round(stats.cpu_ns / 1e6, 3),
        "reaction_ms_p50": round(reaction[len(reaction) // 2], 3) if reaction else None,
        "reaction_ms_p99": round(reaction[(99 * len(reaction)) // 100], 3) if reaction else None,
        "reaction_ms_max": round(reaction[-1], 3) if reaction else None,
    }
    print(f"stats: {json.dumps(out)}", file=sys.stderr, flush=True)
    return 0
