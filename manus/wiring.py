"""Wiring maps: which core method handles which input, on which endpoint each output goes.

Each service declares one :class:`Wiring` (``services/<name>/wiring.py``): its inputs
(a subscribed endpoint -> a core method), its answers (a queryable it owns -> a core
method returning the reply and what to publish) and its outputs (the publications it owns
in the endpoint table, :mod:`schemas.endpoints`). That one declaration drives

- the live shell (:meth:`Wiring.attach`: subscriptions, queryables, one publisher per
  output, all declared at start-up),
- the lock-step harness (``manus_stack.lockstep.LockStep.attach``: the same inputs
  delivered in simulated time, queries as their ``trace/`` mirrors), and
- the regression checker (``manus_stack.regression``: a recording's inputs fed through
  :meth:`Wiring.feed`, the outputs compared),

so a new input reaches all three by one edit. An output the map does not know is a
:class:`WiringError`, the same in every shell: at start-up for what the core declares
(``outputs`` must be the service's own publications), and when a core returns a message
on a key that is not among them.

Handlers take ``(core, message, t_ns)``: ``t_ns`` is the receive time (live), the
delivery time (lock-step) or the log time (replay); cores that take their time from the
message's stamp ignore it. Two more events reach a core through its map, not around it:
a payload of an input that does not decode (``Input.bad``: ``(core, error, t_ns)``) and
a liveliness token ``alive/<service>`` that vanished (``Wiring.token_gone``:
``(core, service, t_ns)``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

from manus.errors import ManusError
from schemas.base import Message
from schemas.endpoints import TABLE, TRACE_PARTS, Endpoint, Kind, Queryable, Topic

C = TypeVar("C")
"""A service core."""
O = TypeVar("O")  # noqa: E741 - the output type of a core's methods
"""What a core's methods return (a list of publications, or a richer value)."""
M = TypeVar("M", bound=Message)
R = TypeVar("R", bound=Message)

Publications = list[tuple[str, Message]]
"""(key suffix, message) pairs to publish."""
ReplyHook = Callable[[Endpoint, Message, Message, float], Message]
"""(queryable, request, reply, seconds taken) -> the reply to send."""


BAD_PAYLOAD = "the payload does not decode"
"""What an input's ``bad`` handler is told of a payload that does not decode (live and
in a replay alike)."""


class WiringError(ManusError):
    """A wiring map that does not fit the endpoint table, or an output it does not know."""


@dataclass(frozen=True)
class Input(Generic[C, M, O]):
    """A subscribed endpoint and the core method that handles its messages.

    Attributes:
        endpoint: the publication subscribed.
        handle: ``(core, message, t_ns) -> outputs``.
        locked: live, run under the node lock (serialised with the other inputs).
        bad: ``(core, error, t_ns) -> outputs`` for a payload that does not decode (None:
            the node only counts it).
    """

    endpoint: Topic[M]
    handle: Callable[[C, M, int], O]
    locked: bool = True
    bad: Callable[[C, str, int], O] | None = None


@dataclass(frozen=True)
class Answer(Generic[C, M, R, O]):
    """A queryable the service owns and the core method that answers it.

    Attributes:
        endpoint: the queryable.
        handle: ``(core, request, t_ns) -> (reply, outputs)``.
        locked: live, run under the node lock (False: the handler takes it itself, for
            long answers such as plans).
    """

    endpoint: Queryable[M, R]
    handle: Callable[[C, M, int], tuple[R, O]]
    locked: bool = True


@dataclass(frozen=True)
class Wiring(Generic[C, O]):
    """One service's wiring (see the module docstring).

    Args:
        service: the service (owner name in the endpoint table).
        publications: the messages to publish in a value the core returns.
        inputs: subscribed endpoints -> core methods.
        answers: owned queryables -> core methods.
        outputs: the publications the core may return; default: every publication the
            service owns in the endpoint table.
        token_gone: ``(core, service, t_ns) -> outputs`` when the liveliness token
            ``alive/<service>`` vanishes (None: the core does not watch tokens).

    Raises:
        WiringError: an endpoint not in the table, an input that is not a publication,
            an answer or output the service does not own.
    """

    service: str
    publications: Callable[[O], Iterable[tuple[str, Message]]]
    inputs: tuple[Input[C, Any, O], ...] = ()
    answers: tuple[Answer[C, Any, Any, O], ...] = ()
    outputs: tuple[Topic[Any], ...] | None = None
    token_gone: Callable[[C, str, int], O] | None = None
    _outputs: dict[str, Endpoint] = field(default_factory=dict, init=False, repr=False)
    _inputs: dict[str, Input[C, Any, O]] = field(default_factory=dict, init=False, repr=False)
    _answers: dict[str, Answer[C, Any, Any, O]] = field(
        default_factory=dict, init=False, repr=False
    )

    def __post_init__(self) -> None:
        for inp in self.inputs:
            self._known(inp.endpoint, Kind.PUBLICATION, owned=False)
            self._inputs[inp.endpoint.suffix] = inp
        for ans in self.answers:
            self._known(ans.endpoint, Kind.QUERYABLE, owned=True)
            self._answers[ans.endpoint.trace(TRACE_PARTS[0])] = ans
        outputs = self.outputs
        if outputs is None:
            found = TABLE.owned_by(self.service, Kind.PUBLICATION)
        else:
            found = [self._known(e, Kind.PUBLICATION, owned=True) for e in outputs]
        self._outputs.update({e.suffix: e for e in found})

    def _known(self, endpoint: Endpoint, kind: Kind, *, owned: bool) -> Endpoint:
        declared = TABLE.get(endpoint.suffix)
        if declared is None:
            raise WiringError(f"{self.service}: {endpoint.suffix!r} is not in the endpoint table")
        if declared.kind is not kind:
            raise WiringError(
                f"{self.service}: {endpoint.suffix!r} is a {declared.kind.value}, not a "
                f"{kind.value}"
            )
        if owned and declared.owner != self.service:
            raise WiringError(
                f"{self.service}: {endpoint.suffix!r} belongs to {declared.owner}, not to "
                f"{self.service} (schemas/endpoints.py)"
            )
        return declared

    # -- what the map says -------------------------------------------------------------------

    @property
    def output_endpoints(self) -> tuple[Endpoint, ...]:
        """The publications this service may publish."""
        return tuple(self._outputs.values())

    def input(self, suffix: str) -> Input[C, Any, O] | None:
        """The input of ``suffix`` (None: not subscribed)."""
        return self._inputs.get(suffix)

    def answer(self, suffix: str) -> Answer[C, Any, Any, O]:
        """The answer of queryable ``suffix``.

        Raises:
            WiringError: the service does not answer it.
        """
        found = next((a for a in self.answers if a.endpoint == suffix), None)
        if found is None:
            raise WiringError(f"{self.service} does not answer {suffix!r}")
        return found

    @property
    def input_suffixes(self) -> tuple[str, ...]:
        """Every key whose messages reach the core: the inputs, then the mirrored
        requests of its queryables (``trace/<q>/request``), in map order."""
        return tuple(i.endpoint.suffix for i in self.inputs) + tuple(
            a.endpoint.trace(TRACE_PARTS[0]) for a in self.answers
        )

    @property
    def output_suffixes(self) -> tuple[str, ...]:
        """Every key the service publishes: its outputs, then its queryables' mirrored
        replies (``trace/<q>/reply``)."""
        return tuple(self._outputs) + tuple(a.endpoint.trace(TRACE_PARTS[1]) for a in self.answers)

    # -- running a core ------------------------------------------------------------------------

    def published(self, out: O) -> Publications:
        """The publications in ``out``, each checked against the outputs.

        Raises:
            WiringError: a message on a key that is not among the service's outputs, or of
                another type than the endpoint's.
        """
        found: Publications = []
        outputs = self._outputs
        for suffix, msg in self.publications(out):
            endpoint = outputs.get(suffix)
            if endpoint is None:
                raise WiringError(
                    f"{self.service}: the core published on {str(suffix)!r}, which is not one "
                    f"of its outputs {sorted(self._outputs)}"
                )
            if type(msg) is not endpoint.msg_type:
                raise WiringError(
                    f"{self.service}: {type(msg).__name__} on {str(suffix)!r}, which carries "
                    f"{getattr(endpoint.msg_type, '__name__', '?')}"
                )
            found.append((suffix, msg))
        return found

    def feed(self, core: C, suffix: str, msg: Message, t_ns: int) -> Publications:
        """Hand one bus message to ``core`` as the live shell would (lock-step, replay).

        An input goes to its handler; ``trace/<q>/request`` of an owned queryable goes to
        its answer, whose reply comes back on ``trace/<q>/reply``. Anything else is not
        for this core: nothing.
        """
        inp = self._inputs.get(suffix)
        if inp is not None:
            return self.published(inp.handle(core, msg, t_ns))
        ans = self._answers.get(suffix)
        if ans is not None:
            reply, out = ans.handle(core, msg, t_ns)
            return [(ans.endpoint.trace(TRACE_PARTS[1]), reply), *self.published(out)]
        return []

    def feed_bad(self, core: C, suffix: str, error: str, t_ns: int) -> Publications:
        """A payload on input ``suffix`` that does not decode, handed to ``core`` as the
        live shell would (nothing when the input has no ``bad`` handler)."""
        inp = self._inputs.get(suffix)
        if inp is None or inp.bad is None:
            return []
        return self.published(inp.bad(core, error, t_ns))

    def feed_token_gone(self, core: C, service: str, t_ns: int) -> Publications:
        """The token ``alive/<service>`` vanished, handed to ``core`` as the live shell
        would (nothing when the map has no ``token_gone``)."""
        if self.token_gone is None:
            return []
        return self.published(self.token_gone(core, service, t_ns))

    def publishers(self, node: Any) -> Callable[[O], None]:
        """Declare a publisher per output on a live ``manus.node.Node``; returns the
        function that publishes what a core returned (checked by :meth:`published`)."""
        pubs = {s: node.publisher(node.keys(s)) for s in self._outputs}

        def publish(out: O) -> None:
            for suffix, msg in self.published(out):
                pubs[suffix].put(msg)

        return publish

    def attach(
        self,
        node: Any,
        core: C,
        sink: Callable[[O], None] | None = None,
        *,
        now: Callable[[], int] | None = None,
        on_reply: ReplyHook | None = None,
        publish: Callable[[O], None] | None = None,
    ) -> Callable[[O], None]:
        """Declare the map on a live ``manus.node.Node``: a publisher per output, a
        subscription per input, a (mirrored) queryable per answer, the inputs' ``bad``
        handlers (``node.on_bad_payload``, under the node lock) and ``token_gone``
        (``node.watch_liveliness``).

        Callbacks may run as soon as a subscription is declared, before this returns: a
        shell whose ``sink`` publishes through the returned function declares the
        publishers first (:meth:`publishers`) and hands them in as ``publish``.

        Args:
            node: the service's node.
            core: the core fed.
            sink: what to do with a handler's return value (default: publish it).
            now: clock of the queries' times [ns] (default ``manus.node.now_ns``).
            on_reply: called with (queryable, request, reply, seconds the answer took)
                after each answer; what it returns is sent (shells log refusals, the
                planner stamps its compute time).
            publish: the publishers' function from :meth:`publishers` (default: made
                here).

        Returns:
            The default sink (publishes what a core returned; the shell calls it for the
            outputs of its own calls, e.g. ticks).
        """
        from manus.node import now_ns  # the node module imports Zenoh: only live shells

        clock = now or now_ns
        if publish is None:
            publish = self.publishers(node)
        deliver = sink or publish
        for inp in self.inputs:
            node.subscribe(
                node.keys(inp.endpoint),
                inp.endpoint.msg_type,
                _input_callback(core, inp, deliver),
                locked=inp.locked,
            )
        for ans in self.answers:
            node.queryable(
                node.keys(ans.endpoint),
                ans.endpoint.msg_type,
                _answer_callback(core, ans, deliver, clock, on_reply),
                locked=ans.locked,
            )
        bad = {node.keys(i.endpoint): i for i in self.inputs if i.bad is not None}
        if bad:

            def on_bad_payload(key: str) -> None:
                inp = bad.get(key)
                if inp is not None and inp.bad is not None:
                    with node.lock:
                        deliver(inp.bad(core, BAD_PAYLOAD, clock()))

            node.on_bad_payload = on_bad_payload
        token_gone = self.token_gone
        if token_gone is not None:

            def on_alive(service: str, alive: bool) -> None:  # called under the node lock
                if not alive:
                    deliver(token_gone(core, service, clock()))

            node.watch_liveliness(on_alive)
        return publish


def _input_callback(
    core: C, inp: Input[C, Any, O], deliver: Callable[[O], None]
) -> Callable[[Message, int], None]:
    def callback(msg: Message, rx_ns: int) -> None:
        deliver(inp.handle(core, msg, rx_ns))

    return callback


def _answer_callback(
    core: C,
    ans: Answer[C, Any, Any, O],
    deliver: Callable[[O], None],
    clock: Callable[[], int],
    on_reply: ReplyHook | None,
) -> Callable[[Message], Message]:
    def callback(request: Message) -> Message:
        started = time.perf_counter()
        reply: Message
        reply, out = ans.handle(core, request, clock())
        deliver(out)
        if on_reply is not None:
            reply = on_reply(ans.endpoint, request, reply, time.perf_counter() - started)
        return reply

    return callback


def messages(out: Iterable[tuple[str, Message]] | None) -> Iterable[tuple[str, Message]]:
    """``publications`` of a core whose methods return (key suffix, message) pairs (or
    None for nothing)."""
    return out or ()
