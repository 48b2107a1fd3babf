"""The jog pad's buttons: each names one direction, turned into a jog command here.

The page sends only a button's name while it is held (every :data:`REPEAT_MS`); the
server builds the :class:`~schemas.jog.JogCommand` from this table, so the browser can ask
for nothing but these motions. Speeds are unitless deflections (full deflection = the
speed level's cap, docs/jog.md) in the arm's base frame, whose axes are the chair's: x
forward, y to the user's left, z up (docs/scene.md).
"""

from __future__ import annotations

from schemas.jog import JogCommand, JogFrame, JogKind, JogUnits

REPEAT_MS = 50
"""How often the page repeats a held button's command [ms]: three per jog deadman
(150 ms), so one late message does not stop the arm, and a lost connection stops it."""

AXES: dict[str, tuple[str, int, float]] = {
    "forward": ("linear", 0, 1.0),
    "back": ("linear", 0, -1.0),
    "left": ("linear", 1, 1.0),
    "right": ("linear", 1, -1.0),
    "up": ("linear", 2, 1.0),
    "down": ("linear", 2, -1.0),
    "open": ("gripper", 0, 1.0),
    "close": ("gripper", 0, -1.0),
}
"""Button name -> (field, index, deflection)."""

LABELS: dict[str, str] = {
    "forward": "Forward",
    "back": "Back",
    "left": "Left",
    "right": "Right",
    "up": "Up",
    "down": "Down",
    "open": "Open hand",
    "close": "Close hand",
}
"""Button name -> its words on the page."""

SOURCE = "panel"
"""``JogCommand.source`` of the panel's commands."""
STALE_MS = 150.0
"""A pad message that reaches the server this much later than the page's fastest ones is
not forwarded [ms]: the controller's jog deadman (``jog_timeout``'s default), so that no
command the deadman would have outlived moves the arm, while the jitter the deadman lets
pass (a late message, a busy server) is let pass here too."""


class Lateness:
    """How late a page's pad messages reach the server, judged on the page's own clock.

    Each message carries when the page sent it (its monotonic clock, ``performance.now()``
    [ms]); the smallest (arrival - sent) seen is the clocks' offset plus the quickest
    trip, and a message later than that by more than :data:`STALE_MS` is stale: it sat in
    a buffer (a network that went silent and came back, a server that was not given the
    CPU). Forwarding it would move the arm on a command the person may have let go of long
    ago, and restart the jog's deadman with it; dropped, the stream's gap stops the arm.
    """

    def __init__(self) -> None:
        self.best: float | None = None
        self.dropped = 0

    def stale(self, sent_ms: float, arrived_ms: float) -> bool:
        """Whether a message sent at ``sent_ms`` (page clock) that arrived at
        ``arrived_ms`` (server clock) is stale (counted in :attr:`dropped`)."""
        offset = arrived_ms - sent_ms
        if self.best is None or offset < self.best:
            self.best = offset
        if offset - self.best > STALE_MS:
            self.dropped += 1
            return True
        return False


def jog_command(axis: str, seq: int, stamp_ns: int) -> JogCommand:
    """The command of the held button ``axis`` (a key of :data:`AXES`).

    Raises:
        KeyError: ``axis`` is not a button of the pad.
    """
    name, index, value = AXES[axis]
    linear = [0.0, 0.0, 0.0]
    gripper = 0.0
    if name == "linear":
        linear[index] = value
    else:
        gripper = value
    return JogCommand(
        stamp_ns=stamp_ns,
        seq=seq,
        source=SOURCE,
        kind=JogKind.TWIST,
        units=JogUnits.UNITLESS,
        frame=JogFrame.BASE,
        linear=linear,
        gripper=gripper,
    )


def stop_command(seq: int, stamp_ns: int) -> JogCommand:
    """The command of a released pad: stop at once (and re-arm the jog)."""
    return JogCommand(
        stamp_ns=stamp_ns, seq=seq, source=SOURCE, kind=JogKind.STOP, units=JogUnits.UNITLESS
    )
