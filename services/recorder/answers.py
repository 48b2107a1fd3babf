"""Answers to live queries from a recording: recorded requests paired with their replies,
and a live request matched to one of them.

Deterministic and Zenoh-free; the replay's stand-in (:mod:`services.recorder.standin`)
calls :meth:`RecordedReplies.answer` for each live query, under its lock.

**Pairing** (:func:`pair_exchanges`). A queryable ``<q>``'s mirrors
``trace/<q>/request`` and ``trace/<q>/reply`` carry the query's receive time as their
publish time (:class:`manus.node.Node`), so a reply pairs with the request of the same
publish time. Recordings without that time (lock-step runs log the controller's reply at
its own simulated time, one bus latency after the request) pair a reply with the earliest
unpaired request logged before it. A reply with neither keeps no request (its request came
before the recording began): it can still serve as a fallback. A request without a reply
(answered with a Zenoh error, which is not mirrored, or never answered) gives nothing to
answer with and is left out.

**Matching** (:meth:`RecordedReplies.answer`). Each queryable's exchanges in the order
their replies were recorded. A live request gets the reply of the first unused exchange
whose recorded request is byte-identical to it (exact); else the reply of the first unused
exchange (a fallback: counted, and the stand-in logs it); each exchange answers once.
When none is left, the answer is an error naming the recording and the queryable.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import NamedTuple

from schemas.endpoints import trace_suffix
from services.recorder.reading import Recorded, Recording


class Exchange(NamedTuple):
    """One recorded query and its reply.

    Attributes:
        request: the recorded request payload (None: its request was not recorded).
        reply: the recorded reply payload, as it travelled.
        query_ns: the reply's publish time: the query's receive time in live recordings [ns].
        rank: index of the reply on its ``trace/<q>/reply`` channel (0-based).
    """

    request: bytes | None
    reply: bytes
    query_ns: int
    rank: int


class Answer(NamedTuple):
    """What to answer a live query with.

    Attributes:
        reply: the recorded reply payload (None: none left, see ``error``).
        exact: the recorded request was byte-identical to the live one.
        rank: index of the recorded reply on its channel (-1: none).
        error: why there is no reply ('' when there is one).
    """

    reply: bytes | None
    exact: bool
    rank: int
    error: str


@dataclass
class AnswerStats:
    """How one queryable's live queries were answered.

    Attributes:
        exact: with the reply to a byte-identical recorded request.
        fallback: with the next unused recorded reply (no identical request left).
        exhausted: with an error: every recorded reply was used.
    """

    exact: int = 0
    fallback: int = 0
    exhausted: int = 0


def pair_exchanges(requests: Sequence[Recorded], replies: Sequence[Recorded]) -> list[Exchange]:
    """The exchanges of one queryable, in reply order (see the module docstring).

    Args:
        requests: its ``trace/<q>/request`` messages in log-time order.
        replies: its ``trace/<q>/reply`` messages in log-time order.
    """
    partner: list[int | None] = [None] * len(replies)
    free = [True] * len(requests)
    by_time: dict[int, list[int]] = {}
    for i, req in enumerate(requests):
        by_time.setdefault(req.publish_ns, []).append(i)
    for j, rep in enumerate(replies):  # the query time, where recorded
        same = [i for i in by_time.get(rep.publish_ns, ()) if free[i]]
        if same:
            partner[j] = same[0]
            free[same[0]] = False
    for j, rep in enumerate(replies):  # else the earliest open request before it
        if partner[j] is None:
            before = (i for i, req in enumerate(requests) if free[i] and req.log_ns <= rep.log_ns)
            first = next(before, None)
            if first is not None:
                partner[j] = first
                free[first] = False
    return [
        Exchange(None if i is None else requests[i].payload, rep.payload, rep.publish_ns, j)
        for j, (rep, i) in enumerate(zip(replies, partner, strict=True))
    ]


class RecordedReplies:
    """Recorded exchanges of some queryables, handed out once each to live queries.

    Args:
        exchanges: queryable suffix (``planner/plan``) -> its exchanges in reply order.
        source: what they come from (the recording's path), for error messages.
    """

    def __init__(self, exchanges: Mapping[str, Sequence[Exchange]], source: str) -> None:
        self.source = source
        self._exchanges = {q: list(ex) for q, ex in exchanges.items()}
        self._used = {q: [False] * len(ex) for q, ex in self._exchanges.items()}
        self.stats: dict[str, AnswerStats] = {q: AnswerStats() for q in self._exchanges}

    @classmethod
    def from_recording(cls, recording: Recording, queryables: Iterable[str]) -> RecordedReplies:
        """The exchanges of ``queryables`` recorded in ``recording`` (none: an empty list).

        Raises:
            RecordingError: a chunk cannot be read.
        """
        exchanges = {}
        for q in queryables:
            request, reply = trace_suffix(q, "request"), trace_suffix(q, "reply")
            found: dict[str, list[Recorded]] = {request: [], reply: []}
            for rec in recording.messages([request, reply]):
                found[rec.suffix].append(rec)
            exchanges[q] = pair_exchanges(found[request], found[reply])
        return cls(exchanges, recording.path)

    @property
    def queryables(self) -> list[str]:
        """The queryables it holds exchanges for (possibly none recorded)."""
        return list(self._exchanges)

    def recorded(self, queryable: str) -> int:
        """Exchanges recorded for ``queryable``."""
        return len(self._exchanges.get(queryable, ()))

    def remaining(self, queryable: str) -> int:
        """Exchanges of ``queryable`` not used yet."""
        return self._used.get(queryable, []).count(False)

    def answer(self, queryable: str, request: bytes) -> Answer:
        """The recorded reply for a live ``request`` on ``queryable`` (and mark it used)."""
        exchanges = self._exchanges.get(queryable, [])
        used = self._used.setdefault(queryable, [])
        stats = self.stats.setdefault(queryable, AnswerStats())
        first_free: int | None = None
        for k, ex in enumerate(exchanges):
            if used[k]:
                continue
            if first_free is None:
                first_free = k
            if ex.request == request:
                used[k] = True
                stats.exact += 1
                return Answer(ex.reply, True, ex.rank, "")
        if first_free is not None:
            used[first_free] = True
            stats.fallback += 1
            ex = exchanges[first_free]
            return Answer(ex.reply, False, ex.rank, "")
        stats.exhausted += 1
        what = f"all {len(exchanges)} used" if exchanges else "none recorded"
        return Answer(
            None,
            False,
            -1,
            f"{self.source}: no recorded reply left for {queryable} ({what}; the replay "
            f"answers each recorded reply once)",
        )
