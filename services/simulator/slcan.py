"""The device end of an slcan adapter as a python-can bus, and the pseudo-terminal link.

The simulator sends and receives through a :class:`can.BusABC` like through any other;
another process opens the client side with python-can's own slcan backend::

    bus = can.Bus(interface="slcan", channel=DEVICE, bitrate=250000, sleep_after_open=0)

so frames cross processes without kernel CAN modules. :class:`SlcanDevice` speaks the
slcan (Lawicel) ASCII protocol as python-can 4.6 uses it (``can/interfaces/slcan.py``): on
open it writes ``C``, ``S5`` (the bitrate), an empty command (its "no data bitrate"),
``O`` and ``O`` again, each ending in CR, and never waits for an answer. Frames are
``tIIIL<data hex>`` (standard data), ``rIIIL`` (standard remote); ``T``/``R`` are the
extended forms. This end answers configuration commands with CR (``V``/``N`` with a
version or serial number), ignores empty commands, answers unknown ones with BEL, and
exchanges frames only while the channel is open (between ``O`` and ``C``); frames sent
while it is closed are dropped and counted, as a real adapter off the bus would.

Two links carry the bytes: :class:`SlcanPtyBus` (here), the master side of a
pseudo-terminal, the client's channel a device path (``/dev/pts/N``), as a USB slcan
adapter's would be; and :class:`~services.simulator.slcan_socket.SlcanSocketBus`, a TCP
server on 127.0.0.1, the client's channel ``socket://127.0.0.1:PORT`` (docs/simulator.md,
Links, says why the stacks use the socket).

The pty's slave is put in raw mode at once and kept open here too, so that a client may
come and go: the master then never reads EIO, and pyserial flushes stale input on open.
"""

from __future__ import annotations

import contextlib
import logging
import os
import pty
import select
import tty
from collections import deque
from pathlib import Path
from typing import Any

import can

log = logging.getLogger("manus.sim.slcan")

CR = b"\r"
BEL = b"\a"
BITRATE_CODES = {
    "S0": 10_000,
    "S1": 20_000,
    "S2": 50_000,
    "S3": 100_000,
    "S4": 125_000,
    "S5": 250_000,
    "S6": 500_000,
    "S7": 750_000,
    "S8": 1_000_000,
    "S9": 83_300,
}
_MAX_LINE = 64


def format_frame(msg: can.Message) -> bytes:
    """The slcan line (with CR) that carries ``msg`` to the client."""
    if msg.is_extended_id:
        head = f"{'R' if msg.is_remote_frame else 'T'}{msg.arbitration_id:08X}{msg.dlc:d}"
    else:
        head = f"{'r' if msg.is_remote_frame else 't'}{msg.arbitration_id:03X}{msg.dlc:d}"
    body = "" if msg.is_remote_frame else bytes(msg.data).hex().upper()
    return (head + body).encode("ascii") + CR


def parse_frame(line: str) -> can.Message | None:
    """The frame of an slcan ``t``/``T``/``r``/``R`` line (no CR); None if malformed."""
    try:
        kind = line[0]
        width = 3 if kind in "tr" else 8
        can_id = int(line[1 : 1 + width], 16)
        dlc = int(line[1 + width])
        remote = kind in "rR"
        data = b"" if remote else bytes.fromhex(line[2 + width : 2 + width + 2 * dlc])
    except (IndexError, ValueError):
        return None
    if (
        dlc > 8
        or (not remote and len(data) != dlc)
        or can_id > (0x7FF if width == 3 else 0x1FFFFFFF)
    ):
        return None
    return can.Message(
        arbitration_id=can_id,
        is_extended_id=width == 8,
        is_remote_frame=remote,
        dlc=dlc,
        data=data,
    )


class SlcanDevice(can.BusABC):
    """The device end of an slcan adapter, on a byte link a subclass provides.

    A subclass waits for and reads the client's bytes in :meth:`_poll` (handing them to
    :meth:`_feed`), writes in :meth:`_write`, and names what to wait on in
    :meth:`wait_fds`.

    Args:
        device: the channel clients open (a pty path, a ``socket://`` URL).
        bitrate: the bus bitrate [bit/s]; a client that sets another is logged.

    Attributes:
        device: the channel clients open.
        is_open: the client has opened the CAN channel (``O``) and not closed it.
        dropped_tx: frames not delivered (channel closed, no client, or not reading).
        bad_lines: malformed lines received from the client.
    """

    def __init__(self, device: str, bitrate: int = 250_000, **kwargs: Any) -> None:
        self.device = device
        self.bitrate = bitrate
        self.is_open = False
        self.dropped_tx = 0
        self.bad_lines = 0
        self._buffer = bytearray()
        self._received: deque[can.Message] = deque()
        super().__init__(channel=device, **kwargs)
        self.channel_info = f"slcan device on {device}"

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Hand ``msg`` to the client (dropped if the channel is closed or the link full)."""
        if not self.is_open:
            self.dropped_tx += 1
            return
        self._write(format_frame(msg))

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        if not self._received:
            self._poll(timeout)
        if self._received:
            return self._received.popleft(), False
        return None, False

    def _poll(self, timeout: float | None) -> None:
        """Wait up to ``timeout`` [s] (None: for ever) for the client, and :meth:`_feed`
        what it wrote."""
        raise NotImplementedError

    def _write(self, data: bytes) -> None:
        """Write ``data`` to the client (count it in ``dropped_tx`` if it cannot be)."""
        raise NotImplementedError

    def wait_fds(self) -> list[int]:
        """The descriptors that become readable when :meth:`_poll` has work."""
        raise NotImplementedError

    def _feed(self, data: bytes) -> None:
        """Bytes from the client: act on each complete line."""
        self._buffer += data
        while True:
            ends = [i for i in (self._buffer.find(b"\r"), self._buffer.find(b"\n")) if i >= 0]
            if not ends:
                if len(self._buffer) > _MAX_LINE:
                    self.bad_lines += 1
                    self._buffer.clear()
                return
            end = min(ends)
            line = self._buffer[:end].decode("ascii", errors="replace")
            del self._buffer[: end + 1]
            self._command(line)

    def _forget_client(self) -> None:
        """The client is gone: the channel is closed and its partial line dropped."""
        self.is_open = False
        self._buffer.clear()

    def _command(self, line: str) -> None:
        if not line:
            return  # python-can writes an empty command for "no data bitrate"
        head = line[0]
        if head in "tTrR":
            msg = parse_frame(line)
            if msg is None:
                self.bad_lines += 1
                self._write(BEL)
            elif self.is_open:
                self._received.append(msg)
            else:
                self._write(BEL)
            return
        if head in "OL":
            self.is_open = True
        elif head == "C":
            self.is_open = False
        elif line in BITRATE_CODES:
            if BITRATE_CODES[line] != self.bitrate:
                log.warning(
                    "slcan client set %d bit/s; the simulated bus runs at %d bit/s",
                    BITRATE_CODES[line],
                    self.bitrate,
                )
        elif head == "V":
            self._write(b"V1013" + CR)
            return
        elif head == "N":
            self._write(b"NMSIM" + CR)
            return
        elif head not in "sFZXWMmQU":
            self._write(BEL)
            return
        self._write(CR)


class SlcanPtyBus(SlcanDevice):
    """The device end of an slcan adapter on a new pseudo-terminal.

    Args:
        channel: optional path of a symbolic link to create to the slave device (so that
            clients can use a fixed name); empty or None: no link.
        bitrate: the bus bitrate [bit/s].

    Attributes:
        device: path of the slave device (e.g. ``/dev/pts/3``) clients open.
    """

    def __init__(self, channel: str | None = None, bitrate: int = 250_000, **kwargs: Any) -> None:
        self._master, self._slave = pty.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.link = Path(channel) if channel else None
        device = os.ttyname(self._slave)
        if self.link is not None:
            if self.link.is_symlink() or self.link.exists():
                self.link.unlink()
            self.link.symlink_to(device)
        super().__init__(device, bitrate, **kwargs)

    def _poll(self, timeout: float | None) -> None:
        ready, _, _ = select.select([self._master], [], [], timeout)
        if ready:
            with contextlib.suppress(BlockingIOError, InterruptedError):
                self._feed(os.read(self._master, 4096))

    def _write(self, data: bytes) -> None:
        try:
            os.write(self._master, data)
        except (BlockingIOError, InterruptedError):
            self.dropped_tx += 1

    def wait_fds(self) -> list[int]:
        """The master side's descriptor (readable when the client wrote something)."""
        return [self._master]

    def shutdown(self) -> None:
        """Close the pseudo-terminal and remove the link (idempotent)."""
        if self._is_shutdown:
            return
        super().shutdown()
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)
        if self.link is not None and self.link.is_symlink():
            self.link.unlink()
