"""The endpoint table: every endpoint by its suffix, checked as it is declared.

:class:`Table` holds the endpoints in declaration order and refuses a suffix declared
twice or one under another endpoint's token root (or under the query mirrors' root);
:func:`markdown_table` renders it for docs/architecture.md. The stack's table is
:data:`schemas.endpoints.TABLE`.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from manus.errors import SchemaError
from schemas.endpoint import TRACE_ROOT, Endpoint, Kind


class Table:
    """The endpoints, by suffix, in declaration order (:data:`TABLE`)."""

    def __init__(self, endpoints: tuple[Endpoint, ...]) -> None:
        self._by_suffix: dict[str, Endpoint] = {}
        self.version = 0
        """Bumped on every change (caches derived from the table compare it)."""
        for endpoint in endpoints:
            self.add(endpoint)

    def add(self, endpoint: Endpoint) -> None:
        """Declare one more endpoint.

        Raises:
            SchemaError: its suffix is taken, or lies under another endpoint's (or the
                trace root).
        """
        suffix = endpoint.suffix
        if suffix in self._by_suffix:
            raise SchemaError(f"endpoint {suffix!r} is declared twice")
        root = suffix.split("/")[0]
        if root == TRACE_ROOT:
            raise SchemaError(f"endpoint {suffix!r}: {TRACE_ROOT}/ holds the query mirrors")
        for other in self._by_suffix.values():
            if other.kind is Kind.LIVELINESS and root == other.suffix:
                raise SchemaError(f"endpoint {suffix!r} lies under the token root {other!r}")
        self._by_suffix[suffix] = endpoint
        self.version += 1

    def remove(self, endpoint: Endpoint) -> None:
        """Withdraw an endpoint (tests that declare a throwaway one)."""
        del self._by_suffix[endpoint.suffix]
        self.version += 1

    @contextlib.contextmanager
    def extended(self, *endpoints: Endpoint) -> Iterator[None]:
        """Declare ``endpoints`` for the duration of a ``with`` block."""
        for endpoint in endpoints:
            self.add(endpoint)
        try:
            yield
        finally:
            for endpoint in endpoints:
                self.remove(endpoint)

    def __iter__(self) -> Iterator[Endpoint]:
        return iter(list(self._by_suffix.values()))

    def __contains__(self, suffix: object) -> bool:
        return suffix in self._by_suffix

    def get(self, suffix: str) -> Endpoint | None:
        """The endpoint of ``suffix`` (None: not declared)."""
        return self._by_suffix.get(suffix)

    def of_kind(self, *kinds: Kind) -> list[Endpoint]:
        """The endpoints of these kinds, in declaration order."""
        return [e for e in self if e.kind in kinds]

    def owned_by(self, owner: str, *kinds: Kind) -> list[Endpoint]:
        """What ``owner`` publishes or answers (of ``kinds``; all kinds when none given)."""
        return [e for e in self if e.owner == owner and (not kinds or e.kind in kinds)]

    def outputs(self, service: str) -> tuple[Endpoint, ...]:
        """What ``service`` publishes (its publications; not the trace mirrors)."""
        return tuple(self.owned_by(service, Kind.PUBLICATION))

    def queryables(self, service: str) -> tuple[Endpoint, ...]:
        """The queryables ``service`` answers."""
        return tuple(self.owned_by(service, Kind.QUERYABLE))


def markdown_table(table: Table) -> str:
    """The key table of docs/architecture.md (kept equal by a test)."""
    rows = [
        "| key (after the prefix) | kind | type | owner | audience |",
        "|---|---|---|---|---|",
    ]
    for e in table:
        if e.kind is Kind.QUERYABLE:
            assert e.msg_type is not None and e.reply_type is not None
            what = f"{e.msg_type.__name__} -> {e.reply_type.__name__}"
        elif e.msg_type is not None:
            what = e.msg_type.__name__
        else:
            what = "(token, no payload)"
        rows.append(f"| `{e.pattern}` | {e.kind.value} | {what} | {e.owner} | {e.audience.value} |")
    return "\n".join(rows) + "\n"
