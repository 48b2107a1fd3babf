"""Replaying a recording onto the bus, in recorded order, at real, scaled or full speed.

:func:`schedule` is the deterministic part: which recorded messages go out, in log-time
order (ties in file order), each with its offset from the first one. :class:`Replayer`
publishes them on Zenoh, under the recording's prefix or another one.

``as_service`` stands in for one service: only the keys that service publishes (its
publications in the endpoint table, :func:`service_outputs_table`) are replayed, so, for
example, ``can_bridge`` feeds a live controller with the recorded arm state while the
controller's own outputs stay live. The stand-in also declares the service's liveliness
tokens (``alive/<service>``, and ``where/<service>/<host>/<pid>`` with the replay's own
host and pid) and answers its queryables (:func:`service_queryables_table`) from the
recorded exchanges, for as long as the :class:`Replayer` is open
(:mod:`services.recorder.standin`; the matching rules are in
:mod:`services.recorder.answers`). The planner publishes only the scene states of
run-time updates: standing in for it is mostly answering ``planner/plan``.

The ``liveliness`` channel (token changes the recorder saw) is a record, not traffic: it
is never published back, neither as samples (nobody listens on that key) nor as tokens
(a replay must not make a live stack, ``manus status`` or the sequencer, believe that the
recorded services run).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass

import zenoh

from manus.node import Node
from manus.session import ZenohSettings
from schemas.endpoints import LIVELINESS, TABLE, Endpoint, Service
from schemas.keys import channel_name
from services.recorder.answers import RecordedReplies
from services.recorder.errors import RecordingError
from services.recorder.reading import Recorded, Recording
from services.recorder.standin import StandIn

REPLAYABLE = (
    Service.CAN_BRIDGE,
    Service.CONTROLLER,
    Service.SIMULATOR,
    Service.SEQUENCER,
    Service.PLANNER,
    Service.GUARDIAN,
)
"""The services ``--as`` accepts."""


def service_outputs_table() -> dict[str, tuple[Endpoint, ...]]:
    """Key suffixes each service publishes (its publications in the endpoint table)."""
    return {s.value: TABLE.outputs(s) for s in REPLAYABLE}


def service_queryables_table() -> dict[str, tuple[Endpoint, ...]]:
    """Queryables each service declares (endpoint table); a stand-in answers them from
    the recording."""
    return {s.value: q for s in REPLAYABLE if (q := TABLE.queryables(s))}


def matching(pub: zenoh.Publisher) -> bool:
    """Whether ``pub`` has a subscriber now (zenoh returns a ``MatchingStatus`` object,
    always truthy, whatever its stub says)."""
    return bool(getattr(pub.matching_status, "matching", False))


@dataclass(frozen=True)
class Scheduled:
    """One message to replay.

    Attributes:
        offset_s: recorded time since the first replayed message [s].
        rec: the recorded message.
    """

    offset_s: float
    rec: Recorded


def selected_suffixes(
    recording: Recording, only: Iterable[str] | None = None, as_service: str | None = None
) -> list[str]:
    """Key suffixes to replay: all, or those matching ``only`` (a suffix, or a prefix
    ending in ``/``, or ``**`` patterns ``state/**``), intersected with ``as_service``'s.
    The ``liveliness`` channel is never replayed (see the module docstring). Standing in
    for a service with recorded query replies, nothing to publish is fine (the planner)
    unless ``only`` asked for something.

    Raises:
        RecordingError: an unknown service, or a selection that matches no channel (and,
            with ``as_service``, no recorded reply of its queryables either).
    """
    channels = {c.suffix for c in recording.info.channels.values()}
    suffixes = sorted(channels - {LIVELINESS})
    if as_service is not None:
        outputs = service_outputs(as_service)
        suffixes = [s for s in suffixes if s in outputs]
    if only:
        patterns = list(only)
        suffixes = [s for s in suffixes if any(_matches(s, p) for p in patterns)]
    if not suffixes:
        queryables = service_queryables_table().get(as_service or "", ())
        replies = [q.trace("reply") for q in queryables]
        if channels.intersection(replies) and not only:
            return []
        what = ""
        if as_service is not None:
            what = (
                f" for --as {as_service}: none of its outputs {list(service_outputs(as_service))}"
            )
            if only:
                what += f" matches --only {list(only)}"
            else:
                what += f" nor a reply of its queryables {replies}" if replies else ""
                what += " is recorded"
        raise RecordingError(
            f"{recording.path}: nothing to replay{what} (channels: {sorted(channels)})"
        )
    return suffixes


def service_outputs(service: str) -> tuple[str, ...]:
    """The key suffixes ``service`` publishes.

    Raises:
        RecordingError: ``service`` is not one of :data:`REPLAYABLE`.
    """
    outputs = service_outputs_table().get(service)
    if outputs is None:
        raise RecordingError(f"--as {service!r}: not one of {sorted(REPLAYABLE)}")
    return outputs


def _matches(suffix: str, pattern: str) -> bool:
    pattern = pattern.removesuffix("**").removesuffix("*")
    if pattern.endswith("/"):
        return suffix.startswith(pattern)
    return suffix == pattern


def schedule(
    recording: Recording, only: Iterable[str] | None = None, as_service: str | None = None
) -> list[Scheduled]:
    """The messages to replay, in order, with their offsets (see :func:`selected_suffixes`)."""
    recs = list(recording.messages(selected_suffixes(recording, only, as_service)))
    if not recs:
        return []
    t0 = recs[0].log_ns
    return [Scheduled((r.log_ns - t0) / 1e9, r) for r in recs]


@dataclass(frozen=True)
class ReplayStats:
    """What a replay published.

    Attributes:
        messages: messages published.
        duration_s: wall time the replay took [s].
        recorded_s: recorded time span replayed [s].
    """

    messages: int
    duration_s: float
    recorded_s: float


class Replayer:
    """Publishes scheduled messages on the bus; with ``as_service``, stands in for that
    service while it is open (its liveliness tokens and queryables, see the module
    docstring).

    Args:
        settings: how to reach the bus; its prefix replaces the recorded one.
        session: an open session to share (not closed by :meth:`close`).
        as_service: the service to stand in for (one of :data:`REPLAYABLE`).
        recording: where the stand-in's answers come from (required with ``as_service``).
        mirror: the stand-in mirrors its live exchanges on ``trace/...`` (as the service
            would; see :mod:`services.recorder.standin`).

    Attributes:
        stand_in: the queryables' side (None without ``as_service``).

    Raises:
        RecordingError: an unknown service, or ``as_service`` without ``recording``.
    """

    def __init__(
        self,
        settings: ZenohSettings,
        *,
        session: zenoh.Session | None = None,
        as_service: str | None = None,
        recording: Recording | None = None,
        mirror: bool = True,
    ) -> None:
        self.stand_in: StandIn | None = None
        if as_service is None:
            self.node = Node("replay", settings, session=session, liveliness=False)
        else:
            service_outputs(as_service)
            if recording is None:
                raise RecordingError(
                    f"replay as {as_service}: a recording to answer from is needed"
                )
            queryables = service_queryables_table().get(as_service, ())
            replies = RecordedReplies.from_recording(recording, queryables)
            self.node = Node(as_service, settings, session=session, liveliness=False)
            self.stand_in = StandIn(self.node, queryables, replies, mirror=mirror)
            self.node.announce()  # its tokens, once its queryables answer
        self._pubs: dict[str, zenoh.Publisher] = {}

    def _publisher(self, suffix: str) -> zenoh.Publisher:
        pub = self._pubs.get(suffix)
        if pub is None:
            pub = self.node.session.declare_publisher(
                self.node.keys(suffix),
                express=True,  # one sample per network message: recorded timing kept
                congestion_control=zenoh.CongestionControl.BLOCK,
                reliability=zenoh.Reliability.RELIABLE,
            )
            self._pubs[suffix] = pub
        return pub

    def wait_for_subscribers(self, suffixes: Iterable[str], timeout: float = 5.0) -> bool:
        """Declare the publishers of ``suffixes`` and wait until each has a subscriber
        (subscriptions take a moment to reach the router). True when all matched."""
        pubs = [self._publisher(s) for s in suffixes]
        deadline = time.monotonic() + timeout
        while not all(matching(p) for p in pubs):
            if time.monotonic() > deadline:
                return False
            time.sleep(0.01)
        return True

    def play(
        self,
        items: list[Scheduled],
        *,
        rate: float | None = 1.0,
        stop: threading.Event | None = None,
    ) -> ReplayStats:
        """Publish ``items`` in order.

        Args:
            items: from :func:`schedule`.
            rate: speed factor (2: twice as fast); None: as fast as possible.
            stop: a ``threading.Event`` that ends the replay early when set.
        """
        if rate is not None and rate <= 0.0:
            raise RecordingError(f"replay rate {rate} must be > 0")
        started = time.monotonic()
        sent = 0
        for item in items:
            if stop is not None and stop.is_set():
                break
            if rate is not None:
                delay = started + item.offset_s / rate - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            rec = item.rec
            traced = channel_name(rec.suffix) != rec.suffix  # a query mirror: its query time
            attachment = rec.publish_ns.to_bytes(8, "little") if traced else None
            self._publisher(rec.suffix).put(rec.payload, attachment=attachment)
            sent += 1
        recorded = items[sent - 1].offset_s if sent else 0.0
        return ReplayStats(sent, time.monotonic() - started, recorded)

    def close(self) -> None:
        """Leave the bus (a stand-in's queryables and tokens go too)."""
        if self.stand_in is not None:
            self.stand_in.close()
        for pub in self._pubs.values():
            pub.undeclare()
        self._pubs.clear()
        self.node.close()

    def __enter__(self) -> Replayer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
