"""A second, minimal implementation of the arm's side of the protocol, over slcan.

Written from docs/protocol.md alone, with the standard library only (nothing of
``manus``, ``services`` or python-can), so that the bridge and the guardian are checked
against something other than the project's own simulator: the 60 ms cycle (0x350 at
+20 ms, 0x360 at +40 ms, the 0x37F remote frame at +60 ms), the status byte (mode in the
low nibble, the message class in bits 7-6), "gripper ready" and "absolute angles
measured" after power-up, joint mode on the first 0x374, and CAN broadcast between its
PC-side ports (each an slcan adapter on a pseudo-terminal of its own), as two adapters
on one bus. It does not move: positions stay where they are (the bridge's start-up moves
of motors 4-6 are a few tenths of a degree, not worth modelling here).
"""

from __future__ import annotations

import contextlib
import os
import pty
import select
import struct
import threading
import time
import tty

CYCLE_S = 0.060
GENERAL = 0x80
"""Message class bits of a general message (docs/protocol.md, Status byte)."""
GRIPPER_READY, ANGLES_MEASURED = 2, 3
JOINT_MODE = 4
POSITIONS = (0, 450, -300, 1793, -368, 826, 400)
"""Encoder fields: joints 1-6 [0.1 deg] and the gripper [0.1 mm]."""


class Port:
    """One PC-side slcan adapter: the master end of a pseudo-terminal."""

    def __init__(self) -> None:
        self.master, self.slave = pty.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        self.device = os.ttyname(self.slave)
        self.is_open = False
        self.buffer = b""

    def lines(self) -> list[str]:
        """The complete lines the PC wrote since the last call."""
        with contextlib.suppress(BlockingIOError):
            self.buffer += os.read(self.master, 4096)
        *done, self.buffer = self.buffer.replace(b"\n", b"\r").split(b"\r")
        return [d.decode("ascii", "replace") for d in done]

    def write(self, line: str) -> None:
        if self.is_open:
            with contextlib.suppress(BlockingIOError):
                os.write(self.master, line.encode("ascii") + b"\r")

    def close(self) -> None:
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):
                os.close(fd)


class TinyArm:
    """The arm behind ``ports`` slcan adapters, run in a thread (a context manager).

    Attributes:
        devices: each port's device, port 0 first.
        moves: 0x374 frames received, per port.
        stops: 0x370 frames received, per port.
    """

    def __init__(self, ports: int = 2) -> None:
        self.ports = [Port() for _ in range(ports)]
        self.devices = [p.device for p in self.ports]
        self.moves = [0] * ports
        self.stops = [0] * ports
        self.mode = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="tiny-arm", daemon=True)

    def __enter__(self) -> TinyArm:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(2.0)
        for port in self.ports:
            port.close()

    def _run(self) -> None:
        t0 = time.monotonic()
        k = 0
        while not self._stop.is_set():
            for offset, send in ((0.020, self._status), (0.040, self._joints), (0.060, self._sync)):
                due = t0 + k * CYCLE_S + offset
                self._listen_until(due)
                send(time.monotonic() - t0)
            k += 1

    def _listen_until(self, due: float) -> None:
        while (left := due - time.monotonic()) > 0 and not self._stop.is_set():
            ready, _, _ = select.select([p.master for p in self.ports], [], [], left)
            for i, port in enumerate(self.ports):
                if port.master in ready:
                    for line in port.lines():
                        self._command(i, line)

    def _command(self, i: int, line: str) -> None:
        port = self.ports[i]
        if not line:
            return
        if line[0] in "OL":
            port.is_open = True
        elif line[0] == "C":
            port.is_open = False
        elif line[0] in "tr" and port.is_open:
            can_id = int(line[1:4], 16)
            if can_id == 0x374:
                self.moves[i] += 1
                self.mode = JOINT_MODE
            elif can_id == 0x370:
                self.stops[i] += 1
            for j, other in enumerate(self.ports):  # one bus: every other node hears it
                if j != i:
                    other.write(line)
            return
        port.write("")  # configuration commands: OK (CR)

    def _broadcast(self, can_id: int, data: bytes | None) -> None:
        if data is None:  # remote frame, DLC 0
            line = f"r{can_id:03X}0"
        else:
            line = f"t{can_id:03X}{len(data)}{data.hex().upper()}"
        for port in self.ports:
            port.write(line)

    def _status(self, t_s: float) -> None:
        code = 0
        status = self.mode
        if self.mode == 0 and t_s >= 0.3:
            code = ANGLES_MEASURED if t_s >= 0.6 else GRIPPER_READY
            status |= GENERAL
        self._broadcast(0x350, struct.pack(">BBhhh", status, code, *POSITIONS[:3]))

    def _joints(self, t_s: float) -> None:
        self._broadcast(0x360, struct.pack(">hhhh", *POSITIONS[3:]))

    def _sync(self, t_s: float) -> None:
        self._broadcast(0x37F, None)
