"""``manus bridge``: the CAN bridge as a process, on any python-can interface.

    manus bridge --can-interface socketcan --can-channel can0      # a real arm
    manus bridge --can-interface pcan --can-channel PCAN_USBBUS1
    manus sim --device-file /tmp/manus-sim.device &                 # the simulator ...
    manus bridge                                                    # ... found through that file

With ``slcan`` (the default) and no ``--can-channel``, the channel is read from the
device file the simulator writes (``--device-file``, default ``$MANUS_SIM_DEVICE_FILE``
or ``/tmp/manus-sim.device``), waiting up to ``--wait-device`` seconds for it. A
single-reader channel (slcan, serial: :mod:`manus.can_sharing`) is locked before it is
opened: a second process that would read it too (a guardian on the same device) is
refused with an error naming the device.

Runs until SIGINT/SIGTERM (or ``--duration``): the arm then gets zeros and 0x370 before
the bus is closed. Prints ``bridge: ...`` when ready and one ``stats:`` JSON line (health
counters) on exit, both on standard error.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import can

from manus.can_sharing import claim_channel
from manus.canbus import open_bus, settles_at_once
from manus.errors import ConfigError
from manus.process import freeze_startup_heap, wait_for_signal
from manus.protocol import BITRATE
from manus.realtime import CAN_EDGE, add_realtime_argument, raise_priority, setting
from manus.session import add_bus_arguments, bus_settings
from schemas import endpoints as ep
from services.can_bridge.config import load_bridge_config
from services.can_bridge.shell import BridgeShell

DEFAULT_DEVICE_FILE = "/tmp/manus-sim.device"
"""Where ``manus bridge`` looks for the simulator's channel by default (see the module doc)."""
GIL_SWITCH_S = 0.0005
"""Interpreter thread switch interval in ``manus bridge`` [s] (Python's default is 5 ms):
a Zenoh callback thread holding the interpreter delays the receive loop by at most this."""
SLCAN_READ_TIMEOUT_S = 0.01
"""Serial read timeout of the slcan backend [s] (see :func:`open_arm_bus`)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``manus bridge``."""
    parser.add_argument(
        "--can-interface", default="slcan", help="python-can interface (default: slcan)"
    )
    parser.add_argument(
        "--can-channel",
        default="",
        help="channel (can0, PCAN_USBBUS1, /dev/ttyACM0 ...); with slcan and none given, "
        "the path in --device-file",
    )
    parser.add_argument("--bitrate", type=int, default=BITRATE, help="bit/s (default 250000)")
    parser.add_argument(
        "--device-file",
        default=os.environ.get("MANUS_SIM_DEVICE_FILE", DEFAULT_DEVICE_FILE),
        help="file holding the simulator's slcan channel (manus sim --device-file)",
    )
    parser.add_argument(
        "--wait-device", type=float, default=10.0, help="wait this long for the device file [s]"
    )
    parser.add_argument("--config", help="bridge config JSON (BridgeConfig field names)")
    add_bus_arguments(parser)
    parser.add_argument("--duration", type=float, help="stop after this many seconds")
    add_realtime_argument(parser, CAN_EDGE)


def resolve_channel(interface: str, channel: str, device_file: str, wait_s: float) -> str:
    """The CAN channel: as given, or (slcan without one) read from the device file.

    Raises:
        ConfigError: no channel and no device file appeared within ``wait_s`` [s].
    """
    if channel or interface != "slcan":
        return channel
    path = Path(device_file)
    deadline = time.monotonic() + wait_s
    while not path.exists():
        if time.monotonic() >= deadline:
            raise ConfigError(
                f"no CAN channel: give --can-channel, or start `manus sim --device-file "
                f"{path}` (no device file {path} after {wait_s:g} s)"
            )
        time.sleep(0.05)
    return path.read_text().strip()


def open_arm_bus(interface: str, channel: str, bitrate: int) -> can.BusABC:
    """Open the arm's bus.

    For slcan, the serial read timeout is raised from python-can's 1 ms to
    ``SLCAN_READ_TIMEOUT_S``: a read returns as soon as a byte is in, so latency is the
    same, but the receive loop no longer wakes a thousand times a second. A
    pseudo-terminal or a socket (the simulator) needs no settle time after opening.
    """
    extra: dict[str, Any] = {}
    if interface == "slcan":
        extra["timeout"] = SLCAN_READ_TIMEOUT_S
        if settles_at_once(channel):
            extra["sleep_after_open"] = 0
    return open_bus(interface, channel, bitrate, **extra)


def run(args: argparse.Namespace) -> int:
    """Bridge the arm until interrupted."""
    config = load_bridge_config(args.config)
    settings = bus_settings(args)
    priority = setting(args, default=CAN_EDGE)
    stop = wait_for_signal()
    sys.setswitchinterval(GIL_SWITCH_S)
    channel = resolve_channel(
        args.can_interface, args.can_channel, args.device_file, args.wait_device
    )
    # a single-reader channel (slcan, serial) is locked first: a second reader is refused
    with claim_channel(args.can_interface, channel, "manus bridge"):
        bus = open_arm_bus(args.can_interface, channel, args.bitrate)
        try:
            with BridgeShell(bus, settings, config) as shell:
                freeze_startup_heap()  # before the cycle runs: no long collections in it
                shell.start()
                raise_priority(priority, "manus bridge")
                print(
                    f"bridge: {args.can_interface} {channel}, "
                    f"serving {shell.node.keys(ep.BRIDGE_COMMAND)}",
                    file=sys.stderr,
                    flush=True,
                )
                stop.wait(args.duration)
                shell.stop(timeout=3.0)
                with shell.lock:
                    state = shell.core.health
                    stats = {
                        "phase": shell.core.phase,
                        **dataclasses.asdict(state),
                        "send_errors": shell.send_errors,
                        "recv_errors": shell.recv_errors,
                    }
        finally:
            bus.shutdown()
    print(f"stats: {json.dumps(stats)}", file=sys.stderr, flush=True)
    return 0
