"""What each service's node says of the input it refused (``manus status``).

Every service's :class:`manus.node.Node` answers the queryable ``<prefix>/health/<name>``
(any payload, which it ignores) with a :class:`NodeHealth`: the payloads that failed to
decode, per key, and the handler errors (a message that decoded but made the service's
code raise, logged and dropped), and the scheduling its process runs at (a real-time
policy or a niceness: :mod:`manus.realtime`). ``manus status`` asks ``health/**`` and
shows them.
"""

from __future__ import annotations

from dataclasses import dataclass

from schemas.base import Message, field


@dataclass(frozen=True)
class HealthRequest(Message):
    """A query of ``health/<service>`` (no fields; the nodes ignore the payload)."""

    TYPE_NAME = "manus/HealthRequest/1"


@dataclass(frozen=True)
class NodeHealth(Message):
    """Bad input one service's node has counted since it started."""

    TYPE_NAME = "manus/NodeHealth/1"

    service: str = field("the service (liveliness name)")
    host: str = field("host name of its computer")
    pid: int = field("its process id", minimum=0)
    bad_payloads: int = field("payloads that failed to decode, on every key", minimum=0)
    bad_keys: list[str] = field("the keys of those payloads", default_factory=list)
    bad_counts: list[int] = field("how many on each of bad_keys", default_factory=list)
    handler_errors: int = field(
        "messages that decoded but made the service's handler raise (logged, dropped)",
        default=0,
        minimum=0,
    )
    scheduling: str = field(
        "its process's scheduling as the kernel reports it: 'rr 10', 'fifo 10' (real-time "
        "policy and priority), 'normal nice 0'; '' from a node that does not say "
        "(manus.realtime, docs/deployment.md)",
        default="",
    )
