"""The boundary to python-can: open any interface, convert frames both ways.

The bridge and the simulator talk to ``can.BusABC`` only, never to one interface kind,
so the same code drives socketcan, pcan, kvaser, slcan or the in-process ``virtual`` bus.
"""

from __future__ import annotations

import os
import socket
from collections.abc import Callable
from typing import Any

import can

from manus.errors import ConfigError
from manus.protocol import BITRATE, Frame

SOCKET_URL = "socket://"
"""How a serial-line channel (slcan) that is a TCP connection begins: pyserial's URL,
``socket://127.0.0.1:PORT`` (the simulator's default link, docs/simulator.md)."""


def is_socket_channel(channel: str) -> bool:
    """Whether ``channel`` is a pyserial ``socket://`` URL rather than a device."""
    return channel.startswith(SOCKET_URL)


def settles_at_once(channel: str) -> bool:
    """Whether an slcan ``channel`` needs no settle time after opening (python-can waits
    2 s for a USB adapter): a pseudo-terminal or a socket, the simulator's links."""
    return channel.startswith("/dev/pts/") or is_socket_channel(channel)


def open_bus(interface: str, channel: str, bitrate: int = BITRATE, **kwargs: Any) -> can.BusABC:
    """Open a python-can bus, with an error that names the interface and channel. A
    ``socket://`` channel gets ``TCP_NODELAY`` (:func:`send_at_once`).

    Raises:
        ConfigError: the interface is unknown or the channel cannot be opened.
    """
    try:
        bus = can.Bus(interface=interface, channel=channel, bitrate=bitrate, **kwargs)
        if is_socket_channel(channel):
            send_at_once(bus)
        return bus
    except (can.CanError, OSError, ValueError, ImportError) as exc:
        raise ConfigError(
            f"cannot open CAN interface {interface!r} channel {channel!r} at {bitrate} bit/s: {exc}"
        ) from exc


def send_at_once(bus: can.BusABC) -> None:
    """Set ``TCP_NODELAY`` on the TCP connection under a ``socket://`` bus.

    pyserial's ``socket://`` leaves Nagle's algorithm on, which holds a small write back
    while an earlier one is unacknowledged; an slcan line is one frame, and a cycle's
    frames must not wait for each other. The option is set through a duplicate of the
    connection's descriptor (the same socket), as pyserial does not expose the socket.
    """
    with socket.socket(fileno=os.dup(bus.fileno())) as sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)


LINE_ERRORS = (ValueError, IndexError)
"""What python-can's serial-line backends (slcan, serial) raise from ``recv`` for a line
they cannot parse (``int('F')`` of a split line, a short line): noise on the line, an
adapter's reset, or bytes another reader of the same line took (``manus.can_sharing``).
The line is consumed before it is parsed, so the next ``recv`` reads the next one."""


def recv(
    bus: can.BusABC, timeout: float | None, on_garbled: Callable[[Exception], None]
) -> can.Message | None:
    """``bus.recv(timeout)``, with a line the backend cannot parse passed to
    ``on_garbled`` (and None returned) instead of raised: one bad line must not end a
    receive loop (the cycle it belonged to is then incomplete, which the bridge handles
    as any lost frame)."""
    try:
        return bus.recv(timeout=timeout)
    except LINE_ERRORS as exc:
        on_garbled(exc)
        return None


def to_can(frame: Frame) -> can.Message:
    """A python-can message for ``frame`` (standard 11-bit id)."""
    return can.Message(
        arbitration_id=frame.id,
        data=frame.data,
        is_remote_frame=frame.remote,
        is_extended_id=False,
        dlc=frame.length,
        timestamp=frame.t_ns / 1e9,
    )


def from_can(msg: can.Message, t_ns: int | None = None) -> Frame:
    """A frame from a python-can message; ``t_ns`` overrides the message's timestamp."""
    stamp = t_ns if t_ns is not None else round(msg.timestamp * 1e9)
    return Frame(
        int(msg.arbitration_id),
        bytes(msg.data) if not msg.is_remote_frame else b"",
        bool(msg.is_remote_frame),
        stamp,
        int(msg.dlc),
    )
