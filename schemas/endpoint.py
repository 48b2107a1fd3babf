"""What an endpoint is: a key suffix with its kind, message types, owner and audience.

An :class:`Endpoint` is a key suffix (under the prefix, default ``manus``) with what it
carries and who owns it. It *is* its suffix (a ``str`` subclass), so it is used wherever a
suffix is: ``Keys(prefix)(JOINTS)`` is ``manus/state/joints``, a core returns
``(FEEDBACK, message)``, a recording's channel is named by it. The endpoints themselves
are declared in :mod:`schemas.endpoints`.

Kinds (:class:`Kind`):

- ``publication``: a stream of one message type, published by its owner (``estop``: by
  anyone; the bridge latches it).
- ``queryable``: request -> reply, answered by its owner. Queries are invisible to
  subscribers, so every answer is mirrored on ``trace/<suffix>/request`` and
  ``trace/<suffix>/reply`` (:meth:`Endpoint.trace`; ``manus.node.Node.queryable``).
- ``liveliness``: a token root: ``alive/<service>`` (the service runs),
  ``where/<service>/<host>/<pid>`` (where each of its processes runs) and
  ``disabled/<service>/<why>`` (it is off on purpose, and why); no payload.
- ``recording``: a channel of recordings only, never published on the bus
  (``liveliness``: the recorder's log of token changes).

Audience (:class:`Audience`): ``supervisor`` endpoints are the public API (documented in
``schemas/supervisor.schema.json``); ``internal`` ones are between the stack's services.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Any, Generic, TypeVar

from manus.errors import SchemaError
from schemas.base import Message

M = TypeVar("M", bound=Message)
R = TypeVar("R", bound=Message)


class Kind(StrEnum):
    """How an endpoint travels (see the module docstring)."""

    PUBLICATION = "publication"
    QUERYABLE = "queryable"
    LIVELINESS = "liveliness"
    RECORDING = "recording"


class Audience(StrEnum):
    """Who uses an endpoint."""

    INTERNAL = "internal"
    """between the stack's own services"""
    SUPERVISOR = "supervisor"
    """the public API: supervisors, user interfaces, other systems"""


class Service(StrEnum):
    """The stack's services, each one process (``manus <command>``) and liveliness name."""

    SIMULATOR = "simulator"
    CAN_BRIDGE = "can_bridge"
    PLANNER = "planner"
    CONTROLLER = "controller"
    SEQUENCER = "sequencer"
    RECORDER = "recorder"
    GUARDIAN = "guardian"


ANYONE = "anyone"
"""Owner of an endpoint every identity may publish on (``estop``)."""
EACH_SERVICE = "each service"
"""Owner of the liveliness roots: each service holds its own tokens under them."""

TRACE_ROOT = "trace"
"""Root of the query mirrors: ``trace/<queryable>/request|reply``."""
TRACE_PARTS = ("request", "reply")


def trace_suffix(queryable: str, part: str) -> str:
    """``trace/<queryable>/<part>``: the suffix of a query mirror (``part``: request or
    reply).

    Raises:
        SchemaError: ``part`` is neither request nor reply.
    """
    if part not in TRACE_PARTS:
        raise SchemaError(f"trace part {part!r} is not one of {list(TRACE_PARTS)}")
    return f"{TRACE_ROOT}/{queryable}/{part}"


class Endpoint(str):
    """One key suffix and what travels on it (a ``str``: the suffix itself).

    Args:
        suffix: the key after the prefix, e.g. ``state/joints``.
        kind: how it travels.
        owner: the service that publishes it or answers it (:data:`ANYONE`,
            :data:`EACH_SERVICE` for the shared ones).
        msg_type: the message type (publications, recording channels), or the request
            type (queryables); None for liveliness roots.
        reply_type: the reply type of a queryable.
        audience: internal or supervisor.
        doc: one line: what it is for.
        params: for a liveliness root, what follows it in a token's key
            (``<service>/<host>/<pid>``).
        clients: for a queryable, the identities besides its owner that may query it
            (the deployed access control, ``manus_stack.policy``); None: every identity.
    """

    kind: Kind
    owner: str
    msg_type: type[Message] | None
    reply_type: type[Message] | None
    audience: Audience
    doc: str
    params: str
    clients: tuple[str, ...] | None

    def __new__(
        cls,
        suffix: str,
        kind: Kind,
        owner: str,
        msg_type: type[Message] | None = None,
        reply_type: type[Message] | None = None,
        *,
        audience: Audience = Audience.INTERNAL,
        doc: str = "",
        params: str = "",
        clients: tuple[str, ...] | None = None,
    ) -> Any:
        if not suffix or suffix.startswith("/") or suffix.endswith("/") or "*" in suffix:
            raise SchemaError(f"endpoint {suffix!r}: a suffix is non-empty, without * or edge /")
        if (kind is Kind.QUERYABLE) != (reply_type is not None):
            raise SchemaError(f"endpoint {suffix!r}: a reply type iff it is a queryable")
        if (kind is Kind.LIVELINESS) != (msg_type is None):
            raise SchemaError(f"endpoint {suffix!r}: a message type unless it is liveliness")
        self = str.__new__(cls, suffix)
        self.kind = kind
        self.owner = owner
        self.msg_type = msg_type
        self.reply_type = reply_type
        self.audience = audience
        self.doc = doc
        self.params = params
        self.clients = clients
        return self

    @property
    def suffix(self) -> str:
        """The key suffix as a plain ``str``."""
        return str.__str__(self)

    @property
    def pattern(self) -> str:
        """The key as documented: the suffix, and the parameters of a token root."""
        return f"{self.suffix}/{self.params}" if self.params else self.suffix

    def trace(self, part: str) -> str:
        """Suffix of this queryable's mirror: ``trace/<suffix>/<part>`` (request, reply).

        Raises:
            SchemaError: not a queryable, or ``part`` is neither request nor reply.
        """
        if self.kind is not Kind.QUERYABLE:
            raise SchemaError(f"{self.suffix}: only a queryable has trace mirrors")
        return trace_suffix(self.suffix, part)

    def __repr__(self) -> str:
        return f"Endpoint({self.suffix!r}, {self.kind.value}, owner {self.owner})"

    def __str__(self) -> str:
        return self.suffix


class Topic(Endpoint, Generic[M]):
    """A publication (or recording channel) carrying messages of type ``M``."""


class Queryable(Endpoint, Generic[M, R]):
    """A queryable: request ``M`` -> reply ``R``."""


def publication(
    suffix: str, owner: str, msg: type[M], doc: str, audience: Audience = Audience.INTERNAL
) -> Topic[M]:
    """The publication ``suffix`` of ``owner``, carrying ``msg``."""
    return Topic(suffix, Kind.PUBLICATION, owner, msg, audience=audience, doc=doc)  # type: ignore[no-any-return]


def queryable(
    suffix: str,
    owner: str,
    request: type[M],
    reply: type[R],
    doc: str,
    audience: Audience = Audience.INTERNAL,
    clients: tuple[str, ...] | None = None,
) -> Queryable[M, R]:
    """The queryable ``suffix`` of ``owner``: ``request`` in, ``reply`` out; ``clients``
    (None: anyone of its audience) may ask it."""
    return Queryable(  # type: ignore[no-any-return]
        suffix,
        Kind.QUERYABLE,
        owner,
        request,
        reply,
        audience=audience,
        doc=doc,
        clients=clients,
    )
