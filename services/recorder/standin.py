"""A service's queryables during a replay, answered from the recording (``manus replay
--as SERVICE``).

:class:`StandIn` declares the queryables of the service it stands in for on a
:class:`~manus.node.Node` named after that service (whose liveliness tokens,
``alive/<service>`` and ``where/<service>/<host>/<pid>``, say the stand-in is up, and
where it really runs) and answers each live query with a recorded reply
(:class:`~services.recorder.answers.RecordedReplies`: the reply to a byte-identical
recorded request, else the next unused one, logged; none left: a Zenoh error reply
naming the recording and the queryable). A request that does not decode to the
queryable's request type is refused with a Zenoh error, as the service itself would.

It mirrors each live exchange on ``trace/<q>/request|reply`` as any queryable of the
stack does (``mirror=True``, the default): a recorder running during the replay then sees
the queries that happened on this bus and the answers given, as if the service ran. It
never republishes the recorded mirrors of its own queryables (they are not among the
service's outputs, so :func:`~services.recorder.replay.schedule` leaves them out), so
nothing is mirrored twice. Error replies are not mirrored (nor are they by ``Node``).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from typing import Any

import zenoh

from manus.errors import SchemaError
from manus.node import Node, now_ns
from schemas.endpoints import trace_suffix
from schemas.keys import channel_type
from services.recorder.answers import RecordedReplies

log = logging.getLogger("manus.replay")


class StandIn:
    """Answers the queryables ``queryables`` from ``replies`` on ``node``.

    Args:
        node: the stand-in's node (named after the service; closed by its owner).
        queryables: key suffixes (``planner/plan``) to answer.
        replies: the recorded exchanges.
        mirror: publish each live request and reply on ``trace/<q>/request|reply``.

    Attributes:
        bad_requests: live requests refused because they did not decode.
    """

    def __init__(
        self,
        node: Node,
        queryables: Iterable[str],
        replies: RecordedReplies,
        *,
        mirror: bool = True,
    ) -> None:
        self.node = node
        self.replies = replies
        self.bad_requests = 0
        self._entities: list[Any] = []
        for suffix in queryables:
            self._declare(suffix, mirror)

    def _declare(self, suffix: str, mirror: bool) -> None:
        request_type = channel_type(trace_suffix(suffix, "request"))
        keys = self.node.keys
        trace: tuple[zenoh.Publisher, zenoh.Publisher] | None = None
        if mirror:
            trace = (
                self._publisher(keys.trace(suffix, "request")),
                self._publisher(keys.trace(suffix, "reply")),
            )

        def on_query(query: zenoh.Query) -> None:
            rx = now_ns()
            payload = query.payload.to_bytes() if query.payload is not None else b""
            if request_type is not None:
                try:
                    request_type.decode(payload)
                except SchemaError as exc:
                    with self.node.lock:
                        self.bad_requests += 1
                    query.reply_err(f"{self.node.name} (replay): {exc}".encode())
                    return
            stamp = rx.to_bytes(8, "little")
            if trace is not None:
                trace[0].put(payload, attachment=stamp)
            with self.node.lock:
                answer = self.replies.answer(suffix, payload)
                left = self.replies.remaining(suffix)
            if answer.reply is None:
                log.warning("replay as %s: %s", self.node.name, answer.error)
                query.reply_err(answer.error.encode())
                return
            if not answer.exact:
                log.warning(
                    "replay as %s: %s: no recorded request identical to this one left; "
                    "answered with recorded reply #%d (%d left)",
                    self.node.name,
                    suffix,
                    answer.rank,
                    left,
                )
            query.reply(query.key_expr, answer.reply)
            if trace is not None:
                trace[1].put(answer.reply, attachment=stamp)

        self._entities.append(self.node.session.declare_queryable(keys(suffix), on_query))

    def _publisher(self, key: str) -> zenoh.Publisher:
        pub = self.node.session.declare_publisher(
            key,
            congestion_control=zenoh.CongestionControl.BLOCK,
            reliability=zenoh.Reliability.RELIABLE,
        )
        self._entities.append(pub)
        return pub

    def close(self) -> None:
        """Stop answering (undeclare the queryables and the mirrors' publishers)."""
        for entity in reversed(self._entities):
            entity.undeclare()
        self._entities.clear()
