"""Liveliness changes as messages: how a recording shows a service appear and vanish.

Services declare Zenoh liveliness tokens, ``<prefix>/alive/<service>`` and
``<prefix>/where/<service>/<host>/<pid>`` (:class:`manus.node.Node`); a token vanishing is
how the stack detects a dead process. Tokens carry no payload and are not samples, so the
recorder turns each change it sees into a :class:`LivelinessChange` and writes them all,
in the order received, on one channel, ``<prefix>/liveliness`` (:data:`LIVELINESS`).

One channel rather than one per token key: a fault is read as a sequence (the bridge's
``where`` token vanished at 12.3 s, a new pid appeared at 14.1 s), and one channel keeps
that sequence in one list (Foxglove's Raw Messages panel; one line in
``manus export --info``); ``where`` keys hold a pid, so a channel per key would add
channels with every restart. One token in Foxglove (a plot or state transitions): a
message path filter, ``/manus/liveliness{key=="manus/alive/can_bridge"}.alive``.

Zenoh merges tokens with the same key: ``alive/<service>`` appears with the first process
that declares it and vanishes with the last, while every process has its own
``where/.../<pid>`` token, so a restart that overlaps the old process shows only there.

``liveliness`` is a recording channel, never a bus key: nobody publishes on it, and the
recorder drops samples published there (:class:`services.recorder.shell.RecorderShell`).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from schemas.base import Message, field

LIVELINESS = "liveliness"
"""Key suffix of the recording channel of liveliness changes (never published)."""


class TokenKind(StrEnum):
    """What a liveliness token says."""

    ALIVE = "alive"
    """``alive/<service>``: the service runs"""
    WHERE = "where"
    """``where/<service>/<host>/<pid>``: where one of its processes runs"""
    OTHER = "other"
    """any other token under the prefix"""


TOKEN_KINDS = tuple(TokenKind)


@dataclass(frozen=True)
class LivelinessChange(Message):
    """A liveliness token under the prefix appeared or vanished (as a recorder saw it)."""

    TYPE_NAME = "manus/LivelinessChange/1"

    stamp_ns: int = field("when the recorder received the change", unit="ns")
    seq: int = field("index of the change in this recording's stream", minimum=0)
    key: str = field("the token's full key expression, e.g. manus/where/planner/base/4711")
    kind: str = field(
        "alive: alive/<service>; where: where/<service>/<host>/<pid>; other: any other token",
        choices=TokenKind,
    )
    service: str = field("the service the token belongs to ('' for other tokens)")
    alive: bool = field(
        "true: the token appeared (or was up when recording began); false: vanished"
    )
    host: str | None = field("host name of a where token (as in its key), else null", default=None)
    pid: int | None = field("process id of a where token, else null", default=None, minimum=0)

    @classmethod
    def from_token(
        cls, key: str, suffix: str, *, alive: bool, stamp_ns: int, seq: int
    ) -> LivelinessChange:
        """The change of the token ``key`` (``suffix``: the key after the prefix).

        Args:
            key: full key expression of the token.
            suffix: ``alive/<service>``, ``where/<service>/<host>/<pid>`` or anything else.
            alive: whether it appeared (Zenoh ``PUT``) or vanished (``DELETE``).
            stamp_ns: receive time [ns].
            seq: index in the stream.
        """
        parts = suffix.split("/")
        kind, service = "other", ""
        host: str | None = None
        pid: int | None = None
        if len(parts) == 2 and parts[0] == "alive" and parts[1]:
            kind, service = "alive", parts[1]
        elif len(parts) == 4 and parts[0] == "where" and parts[1] and parts[3].isdigit():
            kind, service, host, pid = "where", parts[1], parts[2], int(parts[3])
        return cls(
            stamp_ns=stamp_ns,
            seq=seq,
            key=key,
            kind=kind,
            service=service,
            alive=alive,
            host=host,
            pid=pid,
        )


@dataclass(frozen=True)
class TokenGone(Message):
    """A service's ``alive/<service>`` token vanished, as a core took it (keys
    ``controller/token_gone`` and ``bridge/token_gone``), published at once.

    Zenoh drops a token when its session's link closes (a killed process, a router
    restart), so the controller and the bridge stop a goal or a fold at once when the token
    of whoever sends its heartbeats goes (docs/architecture.md, Freshness and safety
    rules). A token is not a sample: this record is the core's input as it took it, after
    which joint state, so a replay feeds it at the same place.
    """

    TYPE_NAME = "manus/TokenGone/1"

    service: str = field("whose token vanished (alive/<service>)")
    after_seq: int = field("seq of the newest joint state the core had (-1: none yet)")
    stopped: str = field("what it stopped, and why ('' when nothing ran that it drove)")
