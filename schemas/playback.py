"""Controlling a running replay (``manus replay``) over the bus, as rosbag2's player offers.

A replay answers ``<prefix>/replay/control`` (``schemas.endpoints.PLAYBACK_CONTROL``): a
:class:`PlaybackControl`
request, a :class:`PlaybackStatus` reply. The replay's own prefix is the one it publishes
under, so a replay onto ``arm2`` is controlled on ``arm2/replay/control``.
"""

from __future__ import annotations

from dataclasses import dataclass

from schemas.base import Message, field

ACTIONS = ("status", "pause", "resume", "step", "seek", "rate")
STATES = ("playing", "paused", "finished")


@dataclass(frozen=True)
class PlaybackControl(Message):
    """Pause, resume, step one message, seek, change the rate, or ask where the replay is."""

    TYPE_NAME = "manus/PlaybackControl/1"

    action: str = field("what to do", choices=ACTIONS)
    value: float = field(
        "seek: the position from the recording's first message [s]; rate: the new time "
        "scale (2: twice as fast); unused otherwise",
        default=0.0,
    )


@dataclass(frozen=True)
class PlaybackStatus(Message):
    """Where the replay is, after the request."""

    TYPE_NAME = "manus/PlaybackStatus/1"

    ok: bool = field("the request was carried out")
    state: str = field("playing, paused or finished", choices=STATES)
    position: float = field("offset of the next message to publish", unit="s")
    duration: float = field("offset of the last message of the selection", unit="s")
    rate: float = field("time scale (0: as fast as possible)")
    published: int = field("messages published so far", minimum=0)
    loop: int = field("pass under way, from 1", minimum=0)
    message: str = field("why it was refused, or what happened", default="")
