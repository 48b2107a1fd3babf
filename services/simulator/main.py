"""``manus sim``: the Manus simulator as a process, a python-can peer on any interface.

    manus sim                                  # an slcan adapter on 127.0.0.1; prints
                                               # "device: socket://127.0.0.1:PORT"
    manus sim --device-file /tmp/manus.dev     # ... and writes that channel there
    manus sim --nodes 2 --device-file /tmp/m.dev   # two PC nodes: /tmp/m.dev, /tmp/m.dev.1
    manus sim --link pty --can-channel /tmp/manus-can  # on a pty instead, plus a symlink
    manus sim --can-interface virtual --can-channel manus   # any python-can interface

The built-in slcan adapter's link (``--link``) is a TCP connection on 127.0.0.1 by
default: a pseudo-terminal's bytes wait in a kernel worker of normal priority, 0.2-0.6 s
under CPU load (docs/simulator.md, Links); ``--link pty`` keeps the serial-device path a
USB adapter has. Clients open either channel with python-can's ``slcan`` interface.
    manus sim --step-response fig51.png        # the thesis's step response, then exit

Runs until SIGINT/SIGTERM (or ``--duration``), then prints one ``stats:`` JSON line
(live timing and counters). With Zenoh (default; skipped with a warning when no router
answers) it publishes the truth on ``<prefix>/sim/truth`` once per cycle, its camera's
frames on ``<prefix>/perception/objects`` (docs/objects.md), its moving target's tracker on
``<prefix>/target/pose`` (when the config's ``target`` is enabled; docs/follow.md) and
answers ``<prefix>/sim/fault`` (switch a fault on at run time,
``services/simulator/fault_desk.py``).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import can

from manus.canbus import open_bus
from manus.errors import ConfigError
from manus.node import Node
from manus.process import freeze_startup_heap, wait_for_signal
from manus.protocol import BITRATE
from manus.realtime import CAN_EDGE, add_realtime_argument, raise_priority, setting
from manus.session import settings_from_env
from schemas import endpoints as ep
from schemas.simfault import SimFault
from schemas.state import SimTruth
from services.simulator.config import SimConfig, load_sim_config
from services.simulator.core import SimCore
from services.simulator.fault_desk import FaultDesk
from services.simulator.live import LiveSim
from services.simulator.nodes import LINKS, NodeHub, slcan_node
from services.simulator.shell import MessagePublisher, TruthPublisher, open_node
from services.simulator.slcan import SlcanDevice
from services.simulator.truth_log import TruthLog

log = logging.getLogger("manus.sim")

SIM_INTERFACE = "slcan-sim"
"""The interface name of the built-in slcan adapter (on the link ``--link`` chooses)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``manus sim``."""
    parser.add_argument(
        "--can-interface",
        default=SIM_INTERFACE,
        help=f"python-can interface, or {SIM_INTERFACE!r} (default): act as an slcan "
        "adapter for another process to open (on the link --link chooses)",
    )
    parser.add_argument(
        "--link",
        choices=LINKS,
        default="tcp",
        help=f"{SIM_INTERFACE}: the adapter's link, a TCP server on 127.0.0.1 (tcp, the "
        "default: no pty kernel worker in the way under load) or a new pseudo-terminal (pty)",
    )
    parser.add_argument(
        "--can-channel",
        default="",
        help=f"channel; with {SIM_INTERFACE} the TCP port (tcp, default: any free one) or "
        "an optional symlink path to the pty device (pty)",
    )
    parser.add_argument("--bitrate", type=int, default=BITRATE, help="bit/s (default 250000)")
    parser.add_argument(
        "--device-file",
        help=f"{SIM_INTERFACE}: write the channel clients open here (a socket:// URL, a pty)",
    )
    parser.add_argument(
        "--nodes",
        type=int,
        default=1,
        help=f"{SIM_INTERFACE}: PC-side nodes on the simulated bus, one link each, with CAN "
        "broadcast between them (node i > 0 announced as '<device-file>.<i>'); default 1",
    )
    parser.add_argument("--config", help="simulator config JSON (default $MANUS_SIM_CONFIG)")
    parser.add_argument("--seed", type=int, help="random seed (overrides the config)")
    parser.add_argument(
        "--objects",
        help="the objects at power-up (overrides the config): an objects file, 'default' (a "
        "cup, a bottle and a phone on the table) or 'none' (docs/objects.md)",
    )
    parser.add_argument(
        "--camera",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="the simulated camera on <prefix>/perception/objects (overrides the config)",
    )
    parser.add_argument(
        "--arm-config",
        help="arm geometry/limits JSON, the same file the other services read (default: "
        "$MANUS_ARM_CONFIG, else thesis values; the simulator config's `arm` overrides it)",
    )
    parser.add_argument(
        "--zenoh",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="publish the truth on <prefix>/sim/truth (skipped if no router answers)",
    )
    parser.add_argument("--zenoh-connect", action="append", help="router endpoint(s)")
    parser.add_argument("--prefix", help="key prefix (default $MANUS_PREFIX or 'manus')")
    parser.add_argument(
        "--truth-log",
        metavar="FILE",
        help="also write the truth to FILE, one line per cycle (services/simulator/truth_log.py)",
    )
    parser.add_argument(
        "--wait-client",
        action=argparse.BooleanOptionalAction,
        default=True,
        help=f"{SIM_INTERFACE}: power the arm up only when a client opens the channel, so "
        "that it sees the power-up messages (default: yes)",
    )
    parser.add_argument(
        "--duration", type=float, help="stop this many seconds after start (waiting included)"
    )
    parser.add_argument(
        "--step-response",
        metavar="PNG",
        help="write the joint 2 step-response plot (the thesis's experiment) and exit",
    )
    add_realtime_argument(parser, CAN_EDGE)


def open_sim_bus(
    interface: str, channel: str, bitrate: int, nodes: int = 1, link: str = "tcp"
) -> can.BusABC:
    """The bus the simulator speaks on (its own slcan adapter on ``link``, one per node
    with ``nodes`` > 1, or any python-can interface: every other peer on its channel is a
    node).

    Raises:
        ConfigError: the adapter cannot be made (a port in use or no number).
    """
    if interface != SIM_INTERFACE:
        return open_bus(interface, channel, bitrate)
    try:
        if nodes > 1:
            return NodeHub(nodes, link, channel or None, bitrate=bitrate)
        return slcan_node(link, channel or None, 0, bitrate)
    except (OSError, ValueError) as exc:
        raise ConfigError(f"manus sim: no slcan adapter on {link} {channel!r}: {exc}") from exc


def write_device_file(path: str, device: str) -> None:
    """Write ``device`` to ``path`` atomically (no newline)."""
    tmp = Path(path + ".tmp")
    tmp.write_text(device)
    tmp.replace(path)


def wait_for_client(
    bus: SlcanDevice | NodeHub, stop: threading.Event, deadline: float | None
) -> None:
    """Block until a client opens the slcan channel, ``stop`` is set or the monotonic
    ``deadline`` [s] passes (frames the client sends meanwhile are discarded)."""
    while not bus.is_open and not stop.is_set():
        if deadline is not None and time.monotonic() >= deadline:
            stop.set()
            return
        bus.recv(timeout=0.1)
    log.info("slcan client opened %s: powering the arm up", bus.channel_info)


def sim_config(args: argparse.Namespace) -> SimConfig:
    """The configuration of the command line: defaults < file < ``--seed``, ``--objects``,
    ``--camera``."""
    config = load_sim_config(args.config, seed=args.seed, arm_config=args.arm_config)
    if args.objects is not None:
        config = config.with_overrides(objects=args.objects)
    if args.camera is not None:
        config = config.with_overrides(camera=replace(config.camera, enabled=args.camera))
    return config


def run(args: argparse.Namespace) -> int:
    """Run the simulator (or write the step-response plot)."""
    config = sim_config(args)
    if args.step_response:
        from services.simulator.stepresponse import plot_step_response

        print(f"plot: {plot_step_response(args.step_response, config)}")
        return 0
    priority = setting(args, default=CAN_EDGE)
    stop = wait_for_signal()
    deadline = None if args.duration is None else time.monotonic() + args.duration
    bus = open_sim_bus(args.can_interface, args.can_channel, args.bitrate, args.nodes, args.link)
    node: Node | None = None
    truth_log: TruthLog | None = None
    try:
        devices = bus.devices if isinstance(bus, NodeHub) else []
        if isinstance(bus, SlcanDevice):
            devices = [bus.device]
        for i, device in enumerate(devices):
            print(f"device: {device}" if i == 0 else f"device {i}: {device}", flush=True)
            if args.device_file:
                write_device_file(args.device_file + (f".{i}" if i else ""), device)
        if args.zenoh:
            node = open_node(settings_from_env(connect=args.zenoh_connect, prefix=args.prefix))
        sinks: list[Callable[[SimTruth], None]] = [TruthPublisher(node)] if node else []
        if args.truth_log:
            truth_log = TruthLog(args.truth_log)
            sinks.append(truth_log)

        def on_snapshot(truth: SimTruth) -> None:
            for sink in sinks:
                sink(truth)

        live = LiveSim(SimCore(config), bus, on_snapshot=on_snapshot if sinks else None)
        if node is not None:
            live.on_message = MessagePublisher(node, lambda: live.wall_t0_ns)
            node.queryable(node.keys(ep.SIM_FAULT), SimFault, FaultDesk(live), locked=False)
            node.announce()
        if isinstance(bus, SlcanDevice | NodeHub) and args.wait_client:
            wait_for_client(bus, stop, deadline)
        if not stop.is_set():
            freeze_startup_heap()
            live.start()
            raise_priority(priority, "manus sim")
            stop.wait(None if deadline is None else max(0.0, deadline - time.monotonic()))
            live.stop()
        stats = {
            "sim_time_s": round(live.sim_time_ns() / 1e9, 3),
            "late_max_ms": round(live.stats.late_max_ms, 3),
            "late_mean_ms": round(live.stats.late_mean_ms, 3),
            "late_over_5ms": live.stats.late_over_5ms,
            "received": live.stats.received,
            **({"received_per_node": bus.received} if isinstance(bus, NodeHub) else {}),
            **live.core.counters.as_dict(),
        }
        print(f"stats: {json.dumps(stats)}", file=sys.stderr, flush=True)
        return 0
    finally:
        if node is not None:
            node.close()
        if truth_log is not None:
            truth_log.close()
        bus.shutdown()
