"""The thin Zenoh shell around a service core: typed publish, subscribe and query.

A :class:`Node` owns one session (from :mod:`manus.session`), declares a liveliness token
``<prefix>/alive/<name>`` while it lives, and a second one,
``<prefix>/where/<name>/<host>/<pid>``, that says on which computer and process it runs
(``manus status``); it turns payloads into typed messages. A
payload that fails to decode is counted per key and logged (at most once a second per
key), never raised into the core: one bad publisher must not take a service down. A
service's node also answers ``<prefix>/health/<name>`` with those counts and its
process's scheduling (``schemas.health.NodeHealth``, shown by ``manus status``).

Callbacks run on Zenoh's threads. Services serialise them into their core with
:attr:`Node.lock` (one lock per node), so the core itself needs no locking. zenoh-python
runs each subscriber's and queryable's callback in a Python thread of its own, so which
of two inputs takes the lock first is up to the scheduler, not to their arrival: a query
can overtake a sample that arrived before it. A node made ``ordered`` runs its callbacks
in the Zenoh thread that receives them (one per link: the router's), in arrival order.

Queries are invisible to subscribers, so every :meth:`Node.queryable` mirrors by default
each request that decodes and each reply it sends on ``<prefix>/trace/<suffix>/request``
and ``<prefix>/trace/<suffix>/reply`` (``schemas.keys.Keys.trace``), both with the same
attachment: the query's receive time [ns] as 8 bytes little-endian, which pairs a reply
with its request (the recorder stores it as the MCAP publish time).
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import time
from collections import Counter
from collections.abc import Callable
from typing import Any, TypeVar

import zenoh

from manus import presence
from manus.errors import ManusError, SchemaError
from manus.realtime import describe
from manus.session import ZenohSettings, open_session
from schemas.base import Message
from schemas.endpoints import ALIVE
from schemas.health import NodeHealth
from schemas.keys import Keys

M = TypeVar("M", bound=Message)
R = TypeVar("R", bound=Message)

log = logging.getLogger("manus.node")


class QueryError(ManusError):
    """A query got no valid reply (no service answered, timeout, or a bad payload)."""


def now_ns() -> int:
    """Wall-clock time [ns] used to stamp messages in live shells."""
    return time.time_ns()


class Publisher:
    """Typed publisher on one key."""

    def __init__(self, pub: zenoh.Publisher) -> None:
        self._pub = pub

    def put(self, msg: Message) -> None:
        """Publish ``msg`` (MessagePack)."""
        self._pub.put(msg.encode())


class Node:
    """One service's presence on the bus.

    Args:
        name: service name (liveliness token ``<prefix>/alive/<name>``).
        settings: how to reach the bus; its ``prefix`` roots every key.
        session: an already open session to use instead (not closed by :meth:`close`).
        liveliness: declare the liveliness tokens now (else with :meth:`announce`).
        pid: the process its ``where`` token names (default: this one; the guardian's
            reporter names the guardian).
        ordered: run every callback in the receiving Zenoh thread, in arrival order
            (else each subscription and queryable in a thread of its own). Its callbacks
            must not wait on the bus (a query from a callback would never get its reply).
    """

    def __init__(
        self,
        name: str,
        settings: ZenohSettings | None = None,
        *,
        session: zenoh.Session | None = None,
        liveliness: bool = True,
        pid: int | None = None,
        ordered: bool = False,
    ) -> None:
        self.name = name
        self.ordered = ordered
        self.pid = os.getpid() if pid is None else pid
        """The process the ``where`` token names (another one's for a helper process)."""
        self.settings = settings or ZenohSettings()
        self.keys = Keys(self.settings.prefix)
        self._own_session = session is None
        self.session = session if session is not None else open_session(self.settings)
        self.lock = threading.RLock()
        self.bad_payloads: Counter[str] = Counter()
        self.handler_errors = 0
        """Messages that decoded but made a handler raise (logged and dropped)."""
        self.on_bad_payload: Callable[[str], None] | None = None
        """Called with the key after each bad payload is counted (on a Zenoh thread, not
        under :attr:`lock`): a service that reports its health live counts them there."""
        self._last_bad_log: dict[str, float] = {}
        self._entities: list[Any] = []
        self._token: zenoh.LivelinessToken | None = None
        self._where: zenoh.LivelinessToken | None = None
        if liveliness:
            self.announce()

    def announce(self) -> None:
        """Declare the liveliness tokens (``alive/<name>``, ``where/<name>/<host>/<pid>``)
        if they are not up yet: a node made with ``liveliness=False`` calls it once its
        queryables are declared, so that whoever sees it alive can query it."""
        if self._token is None:
            self._entities.append(
                self.session.declare_queryable(self.keys.health(self.name), self._on_health)
            )
            live = self.session.liveliness()
            self._token = live.declare_token(self.keys.alive(self.name))
            self._where = live.declare_token(
                self.keys.where(self.name, socket.gethostname(), self.pid)
            )

    def declare_disabled(self, why: str) -> None:
        """Declare ``disabled/<name>/<why>`` (a word): this service is off on purpose, instead
        of :meth:`announce` (``manus status`` shows it; :mod:`manus.presence`)."""
        token = self.session.liveliness().declare_token(self.keys.disabled(self.name, why))
        self._entities.append(token)

    def health(self) -> NodeHealth:
        """The bad input counted so far and the scheduling of :attr:`pid`'s process
        (``schemas.health``)."""
        bad = dict(self.bad_payloads)
        return NodeHealth(
            service=self.name,
            host=socket.gethostname(),
            pid=self.pid,
            bad_payloads=sum(bad.values()),
            bad_keys=list(bad),
            bad_counts=list(bad.values()),
            handler_errors=self.handler_errors,
            scheduling=describe(self.pid),
        )

    def _on_health(self, query: zenoh.Query) -> None:
        query.reply(self.keys.health(self.name), self.health().encode())

    # -- publish / subscribe -------------------------------------------------------------

    def publisher(self, key: str, *, express: bool = True, reliable: bool = True) -> Publisher:
        """A typed publisher on ``key`` (a full key expression).

        ``express`` sends at once without batching (low latency for the control path).
        Samples are never dropped by congestion control: the stack's streams are small
        and a lost command is worse than a late one (the bridge judges freshness).
        """
        pub = self.session.declare_publisher(
            key,
            express=express,
            congestion_control=zenoh.CongestionControl.BLOCK,
            reliability=zenoh.Reliability.RELIABLE if reliable else zenoh.Reliability.BEST_EFFORT,
        )
        self._entities.append(pub)
        return Publisher(pub)

    def subscribe(
        self,
        key: str,
        msg_type: type[M],
        callback: Callable[[M, int], None],
        *,
        locked: bool = True,
    ) -> None:
        """Call ``callback(message, receive_ns)`` for each valid sample on ``key``.

        Args:
            key: key expression (wildcards allowed).
            msg_type: the type every sample must decode to.
            callback: the handler; runs under :attr:`lock` when ``locked``.
            locked: serialise with the other locked callbacks of this node.
        """

        def handler(sample: zenoh.Sample) -> None:
            rx = now_ns()
            if sample.kind != zenoh.SampleKind.PUT:
                return
            try:
                msg = msg_type.decode(sample.payload.to_bytes())
            except SchemaError as exc:
                self._bad(str(sample.key_expr), exc)
                return
            try:
                if locked:
                    with self.lock:
                        callback(msg, rx)
                else:
                    callback(msg, rx)
            except Exception:
                self.handler_errors += 1
                log.exception("%s: handler for %s failed", self.name, sample.key_expr)

        self._entities.append(self.session.declare_subscriber(key, self._callback(handler)))

    def _callback(self, fn: Callable[[Any], None]) -> Any:
        """``fn`` as a Zenoh handler: in the receiving thread if the node is ordered."""
        return zenoh.handlers.Callback(fn, indirect=False) if self.ordered else fn

    def subscribe_raw(self, key: str, callback: Callable[[zenoh.Sample, int], None]) -> None:
        """Call ``callback(sample, receive_ns)`` for every sample (recorders, tools)."""
        self._entities.append(self.session.declare_subscriber(key, lambda s: callback(s, now_ns())))

    # -- queries -------------------------------------------------------------------------

    def queryable(
        self,
        key: str,
        request_type: type[M],
        handler: Callable[[M], Message],
        *,
        locked: bool = True,
        mirror: bool = True,
    ) -> None:
        """Answer queries on ``key``: decode the request, reply with ``handler(request)``.

        A request that fails to decode is counted and answered with a Zenoh error reply
        naming the problem.

        Args:
            key: the queryable's key expression (under the prefix).
            request_type: the type every request must decode to.
            handler: computes the reply; runs under :attr:`lock` when ``locked``.
            locked: serialise with the other locked callbacks of this node.
            mirror: publish each decoded request (before ``handler`` runs) and each reply
                on ``<prefix>/trace/<suffix>/request|reply`` so that recorders see them.
        """
        trace: tuple[zenoh.Publisher, zenoh.Publisher] | None = None
        if mirror:
            suffix = self.keys.suffix(key)
            trace = (
                self._raw_publisher(self.keys.trace(suffix, "request")),
                self._raw_publisher(self.keys.trace(suffix, "reply")),
            )

        def on_query(query: zenoh.Query) -> None:
            rx = now_ns()
            payload = query.payload.to_bytes() if query.payload is not None else b""
            try:
                request = request_type.decode(payload)
            except SchemaError as exc:
                self._bad(str(query.key_expr), exc)
                query.reply_err(str(exc).encode())
                return
            stamp = rx.to_bytes(8, "little")
            if trace is not None:
                trace[0].put(payload, attachment=stamp)
            try:
                if locked:
                    with self.lock:
                        reply = handler(request)
                else:
                    reply = handler(request)
            except Exception as exc:
                self.handler_errors += 1
                log.exception("%s: query handler for %s failed", self.name, query.key_expr)
                query.reply_err(f"{self.name}: internal error: {exc}".encode())
                return
            encoded = reply.encode()
            query.reply(query.key_expr, encoded)
            if trace is not None:
                trace[1].put(encoded, attachment=stamp)

        self._entities.append(self.session.declare_queryable(key, self._callback(on_query)))

    def _raw_publisher(self, key: str) -> zenoh.Publisher:
        pub = self.session.declare_publisher(
            key,
            congestion_control=zenoh.CongestionControl.BLOCK,
            reliability=zenoh.Reliability.RELIABLE,
        )
        self._entities.append(pub)
        return pub

    def query(self, key: str, request: Message, reply_type: type[R], *, timeout: float = 5.0) -> R:
        """Send ``request`` to the queryable on ``key`` and return its typed reply.

        Raises:
            QueryError: nobody answered within ``timeout`` [s], the service replied with
                an error, or the reply did not decode.
        """
        replies = self.session.get(key, payload=request.encode(), timeout=timeout)
        for reply in replies:
            if reply.ok is not None:
                try:
                    return reply_type.decode(reply.ok.payload.to_bytes())
                except SchemaError as exc:
                    raise QueryError(f"{key}: bad reply: {exc}") from exc
            err = reply.err
            text = err.payload.to_bytes().decode(errors="replace") if err is not None else "?"
            raise QueryError(f"{key}: {text}")
        raise QueryError(f"{key}: no reply within {timeout:g} s (is the service running?)")

    # -- liveliness ----------------------------------------------------------------------

    def alive_services(self, timeout: float = 1.0) -> set[str]:
        """Names of the services whose liveliness tokens are up now."""
        return presence.alive_services(self.session, self.keys, timeout)

    def service_hosts(self, timeout: float = 1.0) -> dict[str, list[tuple[str, int]]]:
        """Service name -> [(host name, pid), ...] of every node alive now (``where``)."""
        return presence.service_hosts(self.session, self.keys, timeout)

    def watch_liveliness(self, callback: Callable[[str, bool], None]) -> None:
        """Call ``callback(service, alive)`` when a service's token appears or vanishes."""

        def handler(sample: zenoh.Sample) -> None:
            name = self.keys.suffix(str(sample.key_expr)).removeprefix(f"{ALIVE}/")
            with self.lock:
                callback(name, sample.kind == zenoh.SampleKind.PUT)

        live = self.session.liveliness()
        self._entities.append(
            live.declare_subscriber(self.keys.alive_all, self._callback(handler), history=True)
        )

    def watch_tokens(self, key: str, callback: Callable[[str, bool, int], None]) -> None:
        """Call ``callback(token_key, alive, receive_ns)`` for each liveliness token
        matching ``key`` that appears (those up now included, at once) or vanishes.

        Not serialised with :attr:`lock` (recorders, tools)."""

        def handler(sample: zenoh.Sample) -> None:
            callback(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT, now_ns())

        self._entities.append(
            self.session.liveliness().declare_subscriber(key, handler, history=True)
        )

    # -- housekeeping --------------------------------------------------------------------

    def _bad(self, key: str, exc: Exception) -> None:
        self.bad_payloads[key] += 1
        now = time.monotonic()
        if now - self._last_bad_log.get(key, -10.0) >= 1.0:
            self._last_bad_log[key] = now
            log.warning(
                "%s: bad payload on %s (%d so far): %s", self.name, key, self.bad_payloads[key], exc
            )
        hook = self.on_bad_payload
        if hook is not None:
            hook(key)

    @property
    def bad_payload_count(self) -> int:
        """Bad payloads seen on every key."""
        return sum(self.bad_payloads.values())

    def close(self) -> None:
        """Undeclare everything; close the session if the node opened it."""
        for token in (self._token, self._where):
            if token is not None:
                token.undeclare()
        self._token = self._where = None
        for entity in reversed(self._entities):
            try:
                entity.undeclare()
            except Exception:  # already closed with the session
                log.debug("undeclare failed", exc_info=True)
        self._entities.clear()
        if self._own_session:
            self.session.close()

    def __enter__(self) -> Node:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
