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
