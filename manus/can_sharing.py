"""Who may read a CAN channel: interfaces that share one, and the claim on one that does not.

On a CAN bus every node sees every frame. Some python-can interfaces give every process
that opens a channel its own copy of every frame (:data:`SHARED_INTERFACES`): socketcan
(a socket each), virtual and udp_multicast, socketcand (a connection each), and kvaser
(CANlib lets several handles open one channel, each with its own queue). The others are
taken as **single-reader**. slcan and serial adapters are a byte stream on one serial
line (a tty, a USB CDC-ACM device), and two processes reading one line split its bytes
between them, so each sees garbled frames and misses syncs (seen: a bridge that never
left ``waiting_power_up``, a guardian that took every sync for unanswered and sent 0x370
at each); python-can also writes configuration when it opens an slcan channel (close,
bitrate, open), which disturbs whoever already reads it. USB adapters opened through
libusb (gs_usb, cantact, canalystii ...) admit one process at all. Whether pcan, vector
and the other vendor drivers share a channel depends on the driver and its set-up, so
the guardian gets its own there too.

So the bridge and the CAN guardian never share a single-reader channel:

- :func:`second_reader_refusal` says why a second process (the guardian) may not open a
  channel beside the bridge's; ``manus up`` and ``manus guardian --bridge-channel`` apply
  it (the guardian then stays off and says why: docs/deployment.md, CAN interfaces).
- :func:`claim_channel`: the bridge and the guardian lock a single-reader channel's
  device (``flock``, as pyserial's ``exclusive=True`` does) *before* python-can opens it,
  so a second opener is refused with an error naming the device before it writes or
  reads a byte, whatever started it (a hand-written command, a compose file, a symlink
  such as ``/dev/serial/by-id/...`` to the same device).

The simulator's slcan adapters are TCP servers by default (``socket://127.0.0.1:PORT``,
docs/simulator.md): no device file to lock, so :func:`claim_channel` claims nothing, and
the server itself admits one client at a time (a second connection is closed at once).
:func:`same_channel` compares such URLs by host and port, so the guardian is still kept
off the bridge's.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

from manus.errors import ConfigError

SHARED_INTERFACES = frozenset({"socketcan", "virtual", "udp_multicast", "socketcand", "kvaser"})
"""python-can interfaces on which several processes may open one channel and each
receives every frame. Every other interface is taken as single-reader."""

DISABLED_SINGLE_READER = "single_reader_channel"
"""Why the guardian is off (its ``disabled/guardian/<why>`` token): the bridge's channel
admits one reader and the guardian was given no channel of its own."""
DISABLED_TEXT = {
    DISABLED_SINGLE_READER: "the bridge's CAN channel admits one reader (slcan, serial) and the "
    "guardian has no channel of its own: give it a second adapter on the same bus "
    "(manus up --guardian-channel; compose: MANUS_GUARDIAN_CHANNEL)",
}
"""What each reason word of a ``disabled`` token means (``manus status``)."""


def shares_channel(interface: str) -> bool:
    """Whether several processes may each open a channel of ``interface`` and each
    receive every frame (:data:`SHARED_INTERFACES`)."""
    return interface in SHARED_INTERFACES


def device_path(channel: str) -> Path | None:
    """The device file a serial-line channel names (``/dev/ttyACM0``,
    ``/dev/ttyACM0@115200``), resolved through symbolic links; None for a channel that
    is not a file (``can0``, ``PCAN_USBBUS1``, ``COM3``, a ``socket://`` URL)."""
    port = channel.split("@", 1)[0]
    if not port.startswith("/"):
        return None
    return Path(os.path.realpath(port))


def same_channel(a: str, b: str) -> bool:
    """Whether two channels are one: the same device file (through links), the same
    ``socket://`` host and port (``localhost`` is 127.0.0.1), else the same name."""
    da, db = device_path(a), device_path(b)
    if da is not None and db is not None:
        return da == db
    return _socket_address(a) == _socket_address(b)


def _socket_address(channel: str) -> str:
    """``host:port`` of a ``socket://`` channel (pyserial's options after ``?`` left
    out, ``localhost`` as 127.0.0.1); any other channel unchanged."""
    if not channel.startswith("socket://"):
        return channel
    address = channel.removeprefix("socket://").split("?", 1)[0].rstrip("/").lower()
    host, _, port = address.rpartition(":")
    return f"{'127.0.0.1' if host == 'localhost' else host}:{port}"


def second_reader_refusal(
    interface: str, channel: str, bridge_interface: str, bridge_channel: str
) -> str:
    """Why a second process may not open ``channel`` of ``interface`` beside the bridge,
    which reads ``bridge_channel`` of ``bridge_interface`` ('' when it may: another
    channel, or one that both may share).

    Args:
        interface: python-can interface of the second reader (the guardian).
        channel: its channel.
        bridge_interface: the bridge's interface.
        bridge_channel: the bridge's channel ('' : unknown, nothing to refuse).
    """
    if not bridge_channel or not same_channel(channel, bridge_channel):
        return ""
    if interface == bridge_interface and shares_channel(interface):
        return ""
    return (
        f"{interface} channel {channel} is the bridge's, and {interface} admits one reader "
        "per channel (two readers of one serial line split its bytes): give the guardian "
        "a channel of its own, a second adapter on the same CAN bus"
    )


class ChannelClaim:
    """An exclusive lock on the device file of a single-reader channel, held until
    :meth:`release` (or the end of a ``with`` block, or of the process).

    Args:
        path: the locked device file (None: nothing to lock).
        fd: the descriptor that holds the lock.
    """

    def __init__(self, path: Path | None = None, fd: int | None = None) -> None:
        self.path = path
        self._fd = fd

    def release(self) -> None:
        """Drop the lock (idempotent)."""
        if self._fd is not None:
            with contextlib.suppress(OSError):
                os.close(self._fd)
            self._fd = None

    def __enter__(self) -> ChannelClaim:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def claim_channel(interface: str, channel: str, who: str) -> ChannelClaim:
    """Lock the device of a single-reader ``channel`` for ``who``, before python-can opens
    it (a claim of nothing for a shared interface or a channel that is no device file).

    Raises:
        ConfigError: another process holds the device (it names the device and what to
            do), or the device cannot be opened.
    """
    path = device_path(channel)
    if shares_channel(interface) or path is None:
        return ChannelClaim()
    try:
        import fcntl
    except ImportError:  # not POSIX: no advisory locks; the driver may refuse by itself
        return ChannelClaim()
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
    except OSError as exc:
        raise ConfigError(f"{who}: cannot open {interface} channel {channel}: {exc}") from exc
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        os.close(fd)
        raise ConfigError(
            f"{who}: {interface} channel {channel} ({path}) is held by another process: "
            f"{interface} admits one reader per channel (two readers of one serial line "
            "split its bytes); the bridge and the guardian each need their own adapter "
            "on the CAN bus"
        ) from exc
    return ChannelClaim(path, fd)
