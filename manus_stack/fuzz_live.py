"""Live fuzzing: bad payloads on every key and queryable of a running stack.

The payloads are :mod:`manus_stack.fuzz`'s, keeping only those that do not decode (a
valid message is a command, not bad input: the core-level fuzz gives those to the
cores). Every published key of :func:`schemas.keys.channel_types` gets them as samples,
every queryable as queries; the caller then checks what each service counted
(``health/<service>``, :func:`manus_stack.status.node_health`).
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field
from typing import Any

import zenoh

from manus.errors import SchemaError
from manus_stack.fuzz import KINDS, payloads
from schemas import endpoints as ep
from schemas.base import Message
from schemas.keys import channel_types


@dataclass
class LiveFuzz:
    """What a live fuzz run sent (see :func:`fuzz_live`).

    Attributes:
        sent: bad payloads published per key suffix, or sent as queries per queryable.
        refused: queries answered with an error (the owner refused them).
        unanswered: queries nobody answered (no such queryable up).
    """

    sent: dict[str, int] = field(default_factory=dict)
    refused: dict[str, int] = field(default_factory=dict)
    unanswered: dict[str, int] = field(default_factory=dict)


def bad_payloads(cls: type[Message], count: int, rng: random.Random) -> list[bytes]:
    """``count`` payloads for ``cls`` that do not decode (valid ones are commands, not
    bad input: the core-level fuzz gives those to the cores)."""
    out: list[bytes] = []
    while len(out) < count:
        for _, data in payloads(cls, len(KINDS), rng):
            try:
                cls.decode(data)
            except SchemaError:
                out.append(data)
    return out[:count]


def fuzz_live(node: Any, seed: int, per_endpoint: int, query_timeout: float = 1.0) -> LiveFuzz:
    """Publish bad payloads on every published key of :func:`channel_types` and send them
    as queries to every queryable, through ``node`` (a :class:`manus.node.Node`)."""
    rng = random.Random(seed)
    done = LiveFuzz()
    keys = node.keys
    for channel, cls in sorted(channel_types().items()):
        suffix, _, part = channel.partition("#")
        endpoint = ep.TABLE.get(suffix)
        if part == "reply" or endpoint is None or endpoint.kind is ep.Kind.RECORDING:
            continue  # replies are answers, not input; recording channels are not bus keys
        if endpoint.params:
            continue  # a per-service root (health/<service>): each node ignores the payload
        batch = bad_payloads(cls, per_endpoint, rng)
        done.sent[suffix] = len(batch)
        if part == "request":
            for data in batch:
                replies = list(
                    node.session.get(
                        keys(suffix),
                        payload=data,
                        timeout=query_timeout,
                        congestion_control=zenoh.CongestionControl.BLOCK,  # as the samples
                    )
                )
                if not replies:
                    done.unanswered[suffix] = done.unanswered.get(suffix, 0) + 1
                for reply in replies:
                    if reply.err is not None:
                        done.refused[suffix] = done.refused.get(suffix, 0) + 1
        else:
            # blocking, as every publisher of the stack: a burst under load waits for room
            # in the router's queue rather than being dropped before anyone counts it
            pub = node.session.declare_publisher(
                keys(suffix), congestion_control=zenoh.CongestionControl.BLOCK
            )
            for data in batch:
                pub.put(data)
            pub.undeclare()
    return done
