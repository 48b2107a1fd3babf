"""The device end of an slcan adapter as a TCP server on 127.0.0.1.

The same slcan protocol as :class:`~services.simulator.slcan.SlcanPtyBus`
(:class:`~services.simulator.slcan.SlcanDevice`), carried by a loopback TCP connection
instead of a pseudo-terminal. A client opens it with python-can's slcan backend, which
opens the channel through pyserial's ``serial_for_url``::

    bus = can.Bus(interface="slcan", channel="socket://127.0.0.1:PORT", sleep_after_open=0)

Why: under CPU load the kernel moves a pty's bytes in a kworker of normal priority, so
frames waited 0.2-0.6 s in the pty even with both ends at real-time priority; a loopback
socket's bytes move in the writer's own system call (docs/simulator.md, Links).

One client at a time, as one process holds a serial adapter: a second connection while
one is open is closed at once and logged (two readers of one adapter would split its
bytes: :mod:`manus.can_sharing`). A client may come and go (a bridge restarted): its
leaving closes the CAN channel, and frames sent while no client has it open are dropped
and counted, as on the pty. Small slcan lines go out at once (``TCP_NODELAY``).
"""

from __future__ import annotations

import contextlib
import logging
import select
import socket
from typing import Any

from services.simulator.slcan import SlcanDevice

log = logging.getLogger("manus.sim.slcan")

HOST = "127.0.0.1"
"""Where the server listens: the simulated arm is for this computer only."""


def socket_url(port: int) -> str:
    """The python-can slcan channel of the server on ``port``."""
    return f"socket://{HOST}:{port}"


class SlcanSocketBus(SlcanDevice):
    """The device end of an slcan adapter, a TCP server on 127.0.0.1.

    Args:
        port: TCP port to listen on (0: one the system chooses).
        bitrate: the bus bitrate [bit/s].

    Attributes:
        device: the channel clients open, ``socket://127.0.0.1:PORT``.
        port: the port listened on.
        refused: connections closed because another client held the adapter.
    """

    def __init__(self, port: int = 0, bitrate: int = 250_000, **kwargs: Any) -> None:
        self._server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self._server.bind((HOST, port))
        except OSError:
            self._server.close()
            raise
        self._server.listen(4)
        self._server.setblocking(False)
        self.port: int = self._server.getsockname()[1]
        self.refused = 0
        self._client: socket.socket | None = None
        self._pending = bytearray()
        super().__init__(socket_url(self.port), bitrate, **kwargs)

    @property
    def connected(self) -> bool:
        """A client is connected (whether or not it opened the CAN channel)."""
        return self._client is not None

    def wait_fds(self) -> list[int]:
        """The listening socket's descriptor, and the client's if one is connected."""
        fds = [self._server.fileno()]
        if self._client is not None:
            fds.append(self._client.fileno())
        return fds

    def _poll(self, timeout: float | None) -> None:
        ready, _, _ = select.select(self.wait_fds(), [], [], timeout)
        # the client first: a bridge restarted leaves (EOF) before its successor arrives
        if self._client is not None and self._client.fileno() in ready:
            self._read_client()
        if self._server.fileno() in ready:
            self._accept()

    def _read_client(self) -> None:
        assert self._client is not None
        try:
            data = self._client.recv(4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError as exc:
            log.info("slcan client of %s lost: %s", self.device, exc)
            self._drop_client()
            return
        if not data:
            log.info("slcan client of %s disconnected", self.device)
            self._drop_client()
            return
        self._feed(data)

    def _accept(self) -> None:
        try:
            conn, peer = self._server.accept()
        except (BlockingIOError, InterruptedError):
            return
        if self._client is not None:
            self.refused += 1
            log.warning(
                "slcan %s: refused a second client %s:%d (one client per adapter)",
                self.device,
                *peer,
            )
            conn.close()
            return
        conn.setblocking(False)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._client = conn
        log.info("slcan client %s:%d connected to %s", *peer, self.device)

    def _drop_client(self) -> None:
        if self._client is not None:
            self._client.close()
        self._client = None
        self._pending.clear()
        self._forget_client()

    def _write(self, data: bytes) -> None:
        # whole lines only: the rest of a line the socket took in part goes first, and a
        # line that finds the socket full is dropped, so the client never reads half a line
        if self._client is None:
            self.dropped_tx += 1
            return
        try:
            if self._pending:
                del self._pending[: self._client.send(self._pending)]
                if self._pending:
                    self.dropped_tx += 1
                    return
            sent = self._client.send(data)
        except (BlockingIOError, InterruptedError):
            self.dropped_tx += 1
            return
        except OSError as exc:
            log.info("slcan client of %s lost: %s", self.device, exc)
            self.dropped_tx += 1
            self._drop_client()
            return
        self._pending += data[sent:]

    def shutdown(self) -> None:
        """Close the client's connection and the server (idempotent)."""
        if self._is_shutdown:
            return
        super().shutdown()
        with contextlib.suppress(OSError):
            if self._client is not None:
                self._client.close()
            self._server.close()
