"""Key expressions of one arm, and the message type of every channel, derived from the
endpoint table (:mod:`schemas.endpoints`).

One arm per prefix (default ``manus``). ``Keys(prefix)(endpoint)`` is the concrete key
expression of an endpoint (``Keys()(JOINTS)`` = ``manus/state/joints``);
:func:`channel_types` says which message type travels on each key, which the recorder
uses to give every MCAP channel its JSON Schema. The key table itself is in
docs/architecture.md (made by :func:`schemas.endpoints.markdown_table`).

Queries are invisible to subscribers, so :meth:`manus.node.Node.queryable` mirrors each
decoded request and each reply of queryable ``<q>`` (e.g. ``planner/plan``) on
``trace/<q>/request`` and ``trace/<q>/reply`` (on by default). Both samples carry the
same attachment, the query's receive time [ns] as 8 bytes little-endian, so a reply
pairs with its request. :func:`channel_type` maps these keys to the ``<q>#request`` and
``<q>#reply`` entries of :func:`channel_types`.

``liveliness`` is not a bus key but a recording channel: the recorder writes every change
of the tokens under the prefix there (``schemas.liveliness``); nobody publishes on it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from manus.session import DEFAULT_PREFIX
from schemas.base import Message
from schemas.endpoints import (
    ALIVE,
    DISABLED,
    HEALTH,
    LIVELINESS,
    TABLE,
    TRACE_PARTS,
    TRACE_ROOT,
    WHERE,
    Kind,
    Service,
    trace_suffix,
)

SERVICES = tuple(Service)
"""Names used for liveliness tokens (``<prefix>/alive/<name>``)."""


@dataclass(frozen=True)
class Keys:
    """The key expressions of one arm.

    Attributes:
        prefix: root of every key (one arm per prefix).
    """

    prefix: str = DEFAULT_PREFIX

    def __call__(self, suffix: str) -> str:
        """``<prefix>/<suffix>``."""
        return f"{self.prefix}/{suffix}"

    @property
    def all(self) -> str:
        """Every key of this arm (for recorders)."""
        return f"{self.prefix}/**"

    def alive(self, service: str) -> str:
        """Liveliness token of one service."""
        return self(f"{ALIVE}/{service}")

    @property
    def alive_all(self) -> str:
        return self(f"{ALIVE}/**")

    def where(self, service: str, host: str, pid: int) -> str:
        """Liveliness token saying on which computer (host name) and process a service
        runs; characters a key cannot hold are replaced by ``_``."""
        safe = re.sub(r"[^A-Za-z0-9_.\-]", "_", host) or "unknown"
        return self(f"{WHERE}/{service}/{safe}/{pid}")

    @property
    def where_all(self) -> str:
        return self(f"{WHERE}/**")

    def disabled(self, service: str, why: str) -> str:
        """Liveliness token saying that a service is off on purpose, and why (a word such
        as ``single_reader_channel``)."""
        return self(f"{DISABLED}/{service}/{why}")

    @property
    def disabled_all(self) -> str:
        return self(f"{DISABLED}/**")

    def health(self, service: str) -> str:
        """Queryable of one service's bad-input counts (``schemas.health.NodeHealth``)."""
        return self(f"{HEALTH}/{service}")

    @property
    def health_all(self) -> str:
        return self(f"{HEALTH}/**")

    @property
    def liveliness(self) -> str:
        """The recording channel of liveliness changes (``schemas.liveliness``; not a bus
        key: nobody publishes on it)."""
        return self(LIVELINESS)

    def trace(self, suffix: str, part: str) -> str:
        """Mirror of queryable ``suffix`` (e.g. ``planner/plan``); ``part`` is ``request``
        or ``reply``: ``<prefix>/trace/<suffix>/<part>``."""
        if part not in TRACE_PARTS:
            raise ValueError(f"trace part {part!r} is not 'request' or 'reply'")
        return self(trace_suffix(suffix, part))

    def suffix(self, key: str) -> str:
        """The part of ``key`` after the prefix (``key`` itself if it is not under it)."""
        head = self.prefix + "/"
        return key[len(head) :] if key.startswith(head) else key


def channel_types() -> dict[str, type[Message]]:
    """Key suffix -> message type of every published (non-query) channel, and of the
    recorder's ``liveliness`` channel, from the endpoint table.

    Queryables are listed with their request type under ``<suffix>#request`` and their
    reply type under ``<suffix>#reply`` so that recorders can store both; on the bus they
    travel as ``trace/<suffix>/request|reply`` (:func:`channel_type` maps the keys).
    """
    table: dict[str, type[Message]] = {}
    for e in TABLE:
        if e.kind is Kind.QUERYABLE:
            assert e.msg_type is not None and e.reply_type is not None
            table[f"{e}#request"] = e.msg_type
            table[f"{e}#reply"] = e.reply_type
        elif e.msg_type is not None:
            table[e.suffix] = e.msg_type
    return table


def channel_name(suffix: str) -> str:
    """The :func:`channel_types` name of a key suffix: ``trace/<q>/request`` ->
    ``<q>#request`` (likewise ``reply``); any other suffix is its own name."""
    if suffix.startswith(TRACE_ROOT + "/"):
        head, _, part = suffix[len(TRACE_ROOT) + 1 :].rpartition("/")
        if head and part in TRACE_PARTS:
            return f"{head}#{part}"
    return suffix


def channel_type(suffix: str) -> type[Message] | None:
    """Message type carried on key ``<prefix>/<suffix>`` (trace keys included); None when
    the key is not in the table."""
    if _CACHE.get("version") != TABLE.version:
        _CACHE.clear()
        _CACHE.update(channel_types())
        _CACHE["version"] = TABLE.version
    found = _CACHE.get(channel_name(suffix))
    return found if isinstance(found, type) else None


_CACHE: dict[str, type[Message] | int] = {}
