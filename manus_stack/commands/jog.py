"""``manus jog``: drive the arm from a terminal's keyboard (live control, ``schemas/jog.py``).

A raw-terminal teleop (:mod:`termios`, no curses): it reads keys as they are pressed
(:mod:`manus_stack.teleop` maps them), publishes one JogCommand on ``<prefix>/jog`` every
1 / ``--rate`` seconds (a stop when nothing is held, so the controller's deadman only
matters when this program or its link dies), sets the speed level on
``controller/jog_level``, and redraws a status screen from ``controller/jog_state``,
``state/status`` and ``state/bridge``. The terminal is restored on exit, on Ctrl-C, on
SIGTERM and on a crash. Standard input and output must be a terminal: otherwise it says
so and exits 2.

``--joystick /dev/input/eventN`` adds a game controller or joystick (the ``evdev``
package, ``pip install -e '.[joystick]'``), its axes and buttons mapped by
``--joystick-map FILE`` (:mod:`manus_stack.joystick`); ``--joystick-replay FILE`` plays a
recorded input session instead of a device.
"""

from __future__ import annotations

import argparse
import os
import select
import signal
import sys
import termios
import time
import tty
from types import FrameType
from typing import Any

from manus.errors import ConfigError
from manus.node import Node, QueryError
from manus.session import add_bus_arguments, bus_settings
from manus_stack.joystick import DEFAULT_MAP, Joystick, JoystickMap, RecordedEvents
from manus_stack.teleop import Teleop, screen
from schemas import endpoints as ep
from schemas.control import GoalAck
from schemas.jog import JogCommand, JogLevel, JogState
from schemas.state import ArmStatus, BridgeState

NOT_A_TTY = 2
"""Exit status when standard input or output is not a terminal."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Bus settings, the stream's rate, how long a key holds, a speed level to start at."""
    parser.description = __doc__.split("\n\n")[0] + "\n\n" + _keys_help()
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    add_bus_arguments(parser)
    parser.add_argument("--rate", type=float, default=20.0, help="commands per second (20)")
    parser.add_argument("--hold", type=float, default=0.6, metavar="S",
                        help="a key moves its axis this long after its last press [s]")  # fmt: skip
    parser.add_argument("--deflection", type=float, default=1.0,
                        help="share of the level's speed per key, 0..1 (1)")  # fmt: skip
    parser.add_argument("--level", type=int, default=None, help="speed level to set first")
    parser.add_argument("--joystick", metavar="DEVICE", help="a joystick, /dev/input/eventN")
    parser.add_argument("--joystick-map", metavar="FILE", help="its axis and button mapping")
    parser.add_argument("--joystick-replay", metavar="FILE",
                        help="play a recorded input session instead of a device")  # fmt: skip


def _keys_help() -> str:
    from manus_stack import teleop

    doc = teleop.__doc__ or ""
    return doc[doc.index("Keys") :]


def run(args: argparse.Namespace) -> int:
    """The teleop until q, Ctrl-C or SIGTERM."""
    if not (sys.stdin.isatty() and sys.stdout.isatty()):
        sys.stderr.write(
            "manus jog: standard input and output must be a terminal (a TTY) to read keys; "
            "to drive the arm from a program, publish JogCommand on <prefix>/jog "
            "(examples/jog.py)\n"
        )
        return NOT_A_TTY
    if not 1.0 <= args.rate <= 100.0 or not 0.0 < args.deflection <= 1.0 or args.hold <= 0:
        sys.stderr.write(
            "manus jog: --rate must be in 1..100, --deflection in (0, 1], --hold > 0\n"
        )
        return 2
    teleop, events = _inputs(args)
    with Node("teleop", bus_settings(args), liveliness=False) as node, _Terminal() as term:
        bus = _Bus(node, teleop)
        if args.level is not None:
            bus.set_level(args.level)
        _loop(args, term, bus, teleop, events)
        bus.send({"kind": "stop", "units": "unitless"})
    return 0


def _inputs(args: argparse.Namespace) -> tuple[Teleop, RecordedEvents | _DeviceEvents | None]:
    """The keyboard's teleop, or a joystick's (with its events) beside the keyboard."""
    if not (args.joystick or args.joystick_replay):
        return Teleop(hold_s=args.hold, deflection=args.deflection), None
    if args.joystick_map:
        mapping = JoystickMap.from_file(args.joystick_map)
    else:
        mapping = JoystickMap.from_dict(DEFAULT_MAP)
    events: RecordedEvents | _DeviceEvents
    if args.joystick_replay:
        events = RecordedEvents(args.joystick_replay)
    else:
        events = _DeviceEvents(args.joystick, mapping)
    teleop = Joystick(hold_s=args.hold, deflection=args.deflection, mapping=mapping,
                      ranges=events.ranges)  # fmt: skip
    return teleop, events


def _loop(
    args: argparse.Namespace,
    term: _Terminal,
    bus: _Bus,
    teleop: Teleop,
    events: RecordedEvents | _DeviceEvents | None,
) -> None:
    """Keys and events in, a command every 1 / ``--rate`` s, the screen when it changes."""
    period = 1.0 / args.rate
    shown: list[str] = []
    next_send = time.monotonic()
    while not teleop.quit:
        levels = [teleop.key(ch, time.monotonic()) for ch in term.read(
            max(0.0, next_send - time.monotonic()))]  # fmt: skip
        if events is not None and isinstance(teleop, Joystick):
            levels += [teleop.event(kind, code, value, time.monotonic())
                       for kind, code, value in events.due(time.monotonic())]  # fmt: skip
        for level in levels:
            if level is not None:
                bus.set_level(level)
        now = time.monotonic()
        if now >= next_send:
            bus.send(teleop.command(now))
            next_send = now + period
        latest = bus.latest
        lines = screen(teleop, now, latest.get("jog_state"), latest.get("status"),
                       latest.get("bridge"))  # fmt: skip
        if lines != shown:
            term.draw(lines)
            shown = lines


class _Bus:
    """The teleop's side of the bus: the jog stream out, the level set, the states in."""

    def __init__(self, node: Node, teleop: Teleop) -> None:
        self.node, self.teleop = node, teleop
        keys = node.keys
        self.pub = node.publisher(keys(ep.JOG))
        self.latest: dict[str, Any] = {}
        self.seq = 0
        for name, endpoint, msg_type in (
            ("jog_state", ep.JOG_STATE, JogState),
            ("status", ep.STATUS, ArmStatus),
            ("bridge", ep.BRIDGE_STATE, BridgeState),
        ):
            node.subscribe(keys(endpoint), msg_type, self._keep(name))

    def _keep(self, name: str) -> Any:
        return lambda msg, rx_ns: self.latest.__setitem__(name, msg)

    def send(self, fields: dict[str, Any]) -> None:
        """Publish one JogCommand."""
        self.seq += 1
        self.pub.put(
            JogCommand(stamp_ns=time.time_ns(), seq=self.seq, source="manus jog", **fields)
        )

    def set_level(self, level: int) -> None:
        """Ask the controller for speed level ``level``; the outcome goes on the screen."""
        teleop = self.teleop
        if isinstance(teleop, Joystick):
            teleop.level = level
        try:
            ack = self.node.query(
                self.node.keys(ep.JOG_LEVEL), JogLevel(level=level), GoalAck, timeout=2.0
            )
            teleop.status = f"level {level}" if ack.accepted else f"level refused: {ack.reason}"
        except QueryError as exc:
            teleop.status = f"level not set: {exc}"


class _DeviceEvents:
    """Events of a Linux input device, read without blocking (``evdev``)."""

    def __init__(self, path: str, mapping: JoystickMap) -> None:
        try:
            import evdev  # optional: pip install -e '.[joystick]'
        except ImportError as exc:
            raise ConfigError(
                "--joystick needs the evdev package: pip install -e '.[joystick]'"
            ) from exc
        try:
            self.device = evdev.InputDevice(path)
        except OSError as exc:
            raise ConfigError(f"--joystick {path}: {exc}") from exc
        self.ecodes = evdev.ecodes
        self.known = {*mapping.axes, *mapping.buttons, mapping.enable}
        caps: Any = self.device.capabilities(absinfo=True)  # {EV_ABS: [(code, AbsInfo)]}
        self.ranges = {
            self._name(evdev.ecodes.EV_ABS, code): (info.min, info.max)
            for code, info in caps.get(evdev.ecodes.EV_ABS, [])
        }

    def _name(self, kind: int, code: int) -> str:
        table: Any = self.ecodes.EV if kind < 0 else self.ecodes.bytype.get(kind, {})
        names = table.get(code, str(code))
        if isinstance(names, str):
            return names
        return str(next((n for n in names if n in self.known), names[0]))  # aliases

    def due(self, now_s: float) -> list[tuple[str, str, int]]:
        """The events waiting now."""
        try:
            read = list(self.device.read())
        except BlockingIOError:
            return []
        return [(self._name(-1, e.type), self._name(e.type, e.code), e.value) for e in read]


class _Terminal:
    """Keys one at a time without echo, a redrawn screen, the old settings back on exit."""

    def __init__(self) -> None:
        self.fd = sys.stdin.fileno()
        self.saved: list[Any] | None = None
        self._old_term: Any = None

    def __enter__(self) -> _Terminal:
        self.saved = termios.tcgetattr(self.fd)
        self._old_term = signal.signal(signal.SIGTERM, _terminate)
        tty.setcbreak(self.fd)  # keys at once, no echo; Ctrl-C still interrupts
        sys.stdout.write("\x1b[?25l\x1b[2J")  # hide the cursor, clear
        sys.stdout.flush()
        return self

    def read(self, timeout_s: float) -> str:
        """The keys pressed within ``timeout_s`` [s] (all that are waiting)."""
        ready, _, _ = select.select([self.fd], [], [], timeout_s)
        if not ready:
            return ""
        return os.read(self.fd, 64).decode(errors="replace")

    def draw(self, lines: list[str]) -> None:
        sys.stdout.write("\x1b[H" + "".join(f"{line}\x1b[K\r\n" for line in lines) + "\x1b[J")
        sys.stdout.flush()

    def __exit__(self, *exc: object) -> None:
        if self.saved is not None:
            termios.tcsetattr(self.fd, termios.TCSADRAIN, self.saved)
        signal.signal(signal.SIGTERM, self._old_term)
        sys.stdout.write("\x1b[?25h\r\n")  # the cursor back
        sys.stdout.flush()


def _terminate(signum: int, frame: FrameType | None) -> None:
    raise SystemExit(128 + signum)
