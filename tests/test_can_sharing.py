"""Single-reader CAN channels: the guardian never shares one with the bridge.

The rule (``manus.can_sharing``), the lock on the device, the guardian's channel in
``manus up`` (``manus_stack.guardian_can``), in ``manus guardian`` (it stays off, or is
refused by the lock) and in compose.yaml (the commands the arm computer runs, for the
three ways of setting its variables)."""

from __future__ import annotations

import os
import pty
import re
import subprocess
import sys
import tty
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import can
import pytest
import yaml

from manus.can_sharing import (
    DISABLED_SINGLE_READER,
    claim_channel,
    same_channel,
    second_reader_refusal,
    shares_channel,
)
from manus.canbus import recv
from manus.errors import ConfigError
from manus_stack.cli import build_parser
from manus_stack.guardian_can import guardian_can

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture
def device(tmp_path: Path) -> Iterator[str]:
    """A pseudo-terminal's slave device (a serial line, as an slcan adapter's), and a
    symbolic link to it at ``tmp_path/adapter``."""
    master, slave = pty.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    (tmp_path / "adapter").symlink_to(path)
    try:
        yield path
    finally:
        os.close(slave)
        os.close(master)


def test_socketcan_is_shared_and_a_serial_line_is_not() -> None:
    assert shares_channel("socketcan") and shares_channel("virtual")
    assert not shares_channel("slcan") and not shares_channel("serial")
    assert not shares_channel("gs_usb")  # unknown: taken as single-reader


def test_a_second_reader_is_refused_on_the_bridges_serial_line(device: str, tmp_path: Path) -> None:
    link = str(tmp_path / "adapter")
    assert same_channel(link, device) and same_channel(f"{device}@115200", device)
    why = second_reader_refusal("slcan", link, "slcan", device)
    assert why.startswith(f"slcan channel {link} is the bridge's, and slcan admits one reader")
    assert "a second adapter on the same CAN bus" in why
    assert second_reader_refusal("serial", device, "slcan", device)  # another kind, one line
    assert second_reader_refusal("slcan", "/dev/ttyACM1", "slcan", device) == ""
    assert second_reader_refusal("socketcan", "can0", "socketcan", "can0") == ""
    assert second_reader_refusal("slcan", device, "slcan", "") == ""  # bridge unknown


def test_the_claim_on_a_serial_line_refuses_a_second_process(device: str, tmp_path: Path) -> None:
    with claim_channel("slcan", device, "manus bridge") as claim:
        assert claim.path == Path(device)
        code = (
            "import sys; from manus.can_sharing import claim_channel; "
            "claim_channel('slcan', sys.argv[1], 'manus guardian')"
        )
        link = str(tmp_path / "adapter")  # another name of the same device
        other = subprocess.run(
            [sys.executable, "-c", code, link], cwd=ROOT, capture_output=True, text=True
        )
        assert other.returncode != 0
        assert f"manus guardian: slcan channel {link} ({device}) is held by another process" in (
            other.stderr
        )
    with claim_channel("slcan", device, "manus bridge"):  # released: free again
        pass
    assert claim_channel("socketcan", "can0", "x").path is None  # nothing to lock


def test_manus_up_gives_the_guardian_its_own_channel_or_keeps_it_off() -> None:
    shared = guardian_can("socketcan", "can0")
    assert shared.args[:4] == ["--can-interface", "socketcan", "--can-channel", "can0"]
    assert shared.disabled == "" and shared.note == "guardian: socketcan can0"
    own = guardian_can("slcan", "/dev/ttyACM0", channel="/dev/ttyACM1")
    assert own.args[:4] == ["--can-interface", "slcan", "--can-channel", "/dev/ttyACM1"]
    assert own.args[4:] == ["--bridge-interface", "slcan", "--bridge-channel", "/dev/ttyACM0"]
    assert own.disabled == ""
    off = guardian_can("slcan", "/dev/ttyACM0")
    assert off.disabled == DISABLED_SINGLE_READER and off.note.startswith("guardian: OFF: slcan")
    with pytest.raises(ConfigError, match=r"refused: guardian channel /dev/ttyACM0: slcan chan"):
        guardian_can("slcan", "/dev/ttyACM0", channel="/dev/ttyACM0")


def test_manus_up_refuses_a_guardian_channel_that_is_the_bridges(tmp_path: Path) -> None:
    out = subprocess.run(
        [sys.executable, "-m", "manus_stack.cli", "up", "--run-dir", str(tmp_path / "run"),
         "--endpoint", "tcp/127.0.0.1:9", "--can-interface", "slcan",
         "--can-channel", "/dev/ttyACM0", "--guardian-channel", "/dev/ttyACM0"],
        cwd=ROOT, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert out.returncode == 1
    assert "manus up: error: refused: guardian channel /dev/ttyACM0" in out.stderr
    assert not (tmp_path / "run").exists()  # refused before anything started


def test_the_guardian_stays_off_beside_the_bridges_serial_line(device: str, tmp_path: Path) -> None:
    out = subprocess.run(
        [sys.executable, "-m", "manus_stack.cli", "guardian", "--can-interface", "slcan",
         "--can-channel", str(tmp_path / "adapter"), "--bridge-channel", device,
         "--no-report", "--duration", "0.2"],
        cwd=ROOT, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert "guardian: off: slcan channel" in out.stderr and "stats:" not in out.stderr


def test_the_guardian_is_refused_a_serial_line_the_bridge_holds(device: str) -> None:
    with claim_channel("slcan", device, "manus bridge"):  # as the bridge does
        out = subprocess.run(
            [sys.executable, "-m", "manus_stack.cli", "guardian", "--can-interface", "slcan",
             "--can-channel", device, "--no-report", "--duration", "0.2"],
            cwd=ROOT, capture_output=True, text=True, timeout=60,
        )  # fmt: skip
    assert out.returncode != 0
    assert f"manus guardian: slcan channel {device} ({device}) is held by another" in out.stderr


# -- compose.yaml -------------------------------------------------------------------------------

_VAR = re.compile(r"\$\{(\w+)(?::([-?])((?:[^${}]|\$\{[^{}]*\})*))?\}")


def _interpolate(text: str, env: dict[str, str]) -> str:
    """Compose's ``${VAR}``, ``${VAR:-default}`` (nested) and ``${VAR:?error}``."""

    def one(m: re.Match[str]) -> str:
        name, op, rest = m.group(1), m.group(2), m.group(3) or ""
        if env.get(name):
            return env[name]
        if op == "?":
            raise KeyError(f"{name}: {rest}")
        return _interpolate(rest, env) if op == "-" else ""

    return _VAR.sub(one, text)


def _service(name: str, env: dict[str, str], *files: str) -> dict[str, Any]:
    """Service ``name`` of compose.yaml (and the override ``files``) under ``env``."""
    merged: dict[str, Any] = {}
    for file in ("compose.yaml", *files):
        data = yaml.safe_load(_interpolate((ROOT / file).read_text(), env))
        merged |= data["services"].get(name, {})
    return merged


def _guardian_refusal(env: dict[str, str]) -> tuple[str, str]:
    """(the guardian's channel, why it stays off) under compose with ``env``."""
    command = _service("guardian", env)["command"]
    args = build_parser("guardian").parse_args(command)
    bridge = build_parser("bridge").parse_args(_service("can-bridge", env)["command"])
    assert (args.bridge_interface, args.bridge_channel) == (
        bridge.can_interface,
        bridge.can_channel,
    )
    why = second_reader_refusal(
        args.can_interface, args.can_channel, args.bridge_interface, args.bridge_channel
    )
    return args.can_channel, why


def test_compose_keeps_socketcan_shared_and_slcan_on_two_adapters() -> None:
    assert _guardian_refusal({}) == ("can0", "")  # socketcan: one channel, both nodes
    slcan = {"MANUS_CAN_INTERFACE": "slcan", "MANUS_CAN_CHANNEL": "/dev/ttyACM0"}
    channel, why = _guardian_refusal(slcan)
    assert channel == "/dev/ttyACM0" and "admits one reader" in why  # stays off
    own = _guardian_refusal(slcan | {"MANUS_GUARDIAN_CHANNEL": "/dev/ttyACM1"})
    assert own == ("/dev/ttyACM1", "")
    # the serial devices reach each container; both must be named
    env = slcan | {"MANUS_GUARDIAN_CHANNEL": "/dev/ttyACM1"}
    assert _service("guardian", env, "deploy/compose.slcan.yaml")["devices"] == ["/dev/ttyACM1"]
    assert _service("can-bridge", env, "deploy/compose.slcan.yaml")["devices"] == ["/dev/ttyACM0"]
    with pytest.raises(KeyError, match="MANUS_GUARDIAN_CHANNEL: the guardian's own adapter"):
        _service("guardian", slcan, "deploy/compose.slcan.yaml")


def test_a_garbled_serial_line_is_dropped_not_raised() -> None:
    """What two readers of one line left the bridge with (a line split in two: python-can
    raised ``int('F')`` and the bridge's receive thread died, its token still up)."""
    master, slave = pty.openpty()  # the master plays the adapter
    tty.setraw(slave)
    bus = can.Bus(interface="slcan", channel=os.ttyname(slave), bitrate=250_000,
                  sleep_after_open=0, timeout=0.05)  # fmt: skip
    try:
        garbled: list[Exception] = []
        os.write(master, b"t35F\r")  # the tail of 0x350's line: no length digit
        with pytest.raises(ValueError):
            bus.recv(timeout=1.0)  # python-can itself raises
        os.write(master, b"t35F\rr37F0\r")
        assert recv(bus, 1.0, garbled.append) is None and len(garbled) == 1
        msg = recv(bus, 1.0, garbled.append)  # the next line is read as before
        assert msg is not None and msg.arbitration_id == 0x37F and msg.is_remote_frame
    finally:
        bus.shutdown()
        os.close(slave)
        os.close(master)
