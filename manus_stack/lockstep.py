"""Lock-step simulation: simulator core + bridge core (+ subscribers) on one simulated clock.

Everything runs in one thread in time order, with no Zenoh and no wall clock, so a 20 s
path takes a fraction of a second and gives the same result on every run:

- the arm's frames reach the bridge when the simulator sends them (``on_frame`` with
  ``now`` = the frame's time);
- the bridge's frames reach the simulator ``reply_latency_ns`` later;
- every message published (by the bridge, by a subscriber, or with :meth:`LockStep.publish`)
  is recorded in :attr:`LockStep.messages` and delivered ``bus_latency_ns`` later to the
  subscribers of its key suffix, and to the bridge's inputs (its wiring map,
  :data:`services.can_bridge.wiring.WIRING`: velocity commands, e-stops);
- a core attached with :meth:`LockStep.attach` gets what its service's wiring map
  subscribes, its queryables' requests as their ``trace/<q>/request`` mirrors (its
  answers go out on ``trace/<q>/reply``), as the live shells wire them;
- the simulator's own publications (its camera's frames on ``perception/objects``, its
  moving target's tracker on ``target/pose``,
  :meth:`services.simulator.core.SimCore.take_messages`) are published when it makes them;
- the bridge's ``on_tick`` runs every 20 ms;
- other PC-side nodes on the bus (:meth:`LockStep.attach_node`, e.g. the guardian) get
  every frame of the arm and of the bridge, and theirs reach the arm and the bridge, each
  ``reply_latency_ns`` after it left (CAN broadcast); :meth:`LockStep.pause_bridge` stops
  the bridge as SIGSTOP would (frames to it wait, messages to it are dropped),
  :meth:`LockStep.resume_bridge` hands it the waiting frames at once (``kill=True``:
  never again) and :meth:`LockStep.restart_bridge` starts a new one;
- :meth:`LockStep.token_gone` is a liveliness token vanishing (a process killed, a link
  cut): the bridge and the watchers (:meth:`LockStep.watch_tokens`) take it at once.

Events at the same instant run in this order: the simulator, then message deliveries (in
publication order), then the tick.
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

from manus.protocol import Frame
from manus.wiring import Wiring
from schemas import endpoints as ep
from schemas.base import Message
from schemas.commands import ArmCommand, ArmCommandReply
from services.can_bridge.core import BridgeConfig, BridgeCore, Outputs
from services.can_bridge.wiring import WIRING as BRIDGE
from services.simulator.config import SimConfig
from services.simulator.core import SimCore

Handler = Callable[[Message, int], list[tuple[str, Message]]]
"""A subscriber: (message, delivery time [ns]) -> messages to publish (key suffix, message)."""
TokenWatcher = Callable[[str, int], list[tuple[str, Message]]]
"""A liveliness watcher: (service whose token vanished, time [ns]) -> messages to publish."""

TICK_NS = 20_000_000
"""Period of the bridge's ``on_tick`` [ns]."""

C = TypeVar("C")


class BusNode(Protocol):
    """Another PC-side node on the arm's bus (see :meth:`LockStep.attach_node`)."""

    def receive(self, frame: Frame) -> None:
        """A frame of the arm or of another node, stamped with its arrival time."""

    def next_event_ns(self) -> int | None:
        """When the node next wants to act [ns] (None: only on a frame)."""

    def advance(self, t_ns: int) -> list[Frame]:
        """Act at ``t_ns``; returns the frames it sends now."""


@dataclass(frozen=True)
class _Delivery:
    suffix: str
    msg: Message


@dataclass(frozen=True)
class _FrameTo:
    node: BusNode | None  # None: the bridge
    frame: Frame


class LockStep:
    """Simulator and bridge cores in time order (see the module docstring).

    Args:
        sim: simulator settings (default: :class:`SimConfig` defaults, seed 0).
        bridge: bridge settings.
        reply_latency_ns: time from a frame leaving the bridge to its arrival at the arm [ns].
        bus_latency_ns: time from a publication to its delivery [ns].
    """

    def __init__(
        self,
        sim: SimConfig | None = None,
        bridge: BridgeConfig | None = None,
        *,
        reply_latency_ns: int = 1_000_000,
        bus_latency_ns: int = 200_000,
    ) -> None:
        if reply_latency_ns < 0 or bus_latency_ns < 0:
            raise ValueError(
                f"latencies must be >= 0 ns, got reply {reply_latency_ns}, bus {bus_latency_ns}"
            )
        self.sim = SimCore(sim)
        self.bridge = BridgeCore(bridge)
        self.reply_latency_ns = reply_latency_ns
        self.bus_latency_ns = bus_latency_ns
        self.messages: list[tuple[int, str, Message]] = []
        """Every message published, with its publication time [ns], in order."""
        self.arm_frames: list[Frame] = []
        """Every frame the arm sent (stamped with its send time)."""
        self.bridge_frames: list[Frame] = []
        """Every frame the bridge sent (stamped with its send time)."""
        self._t = 0
        self._next_tick = TICK_NS
        self._order = itertools.count()
        self._queue: list[tuple[int, int, _Delivery | _FrameTo]] = []
        self._subs: dict[str, list[Handler]] = {}
        self.nodes: list[BusNode] = []
        """Other PC-side nodes on the bus (:meth:`attach_node`)."""
        self.node_frames: list[Frame] = []
        """Every frame the other nodes sent (stamped with its send time)."""
        self._bridge_paused = False
        self._bridge_killed = False
        self._bridge_backlog: list[Frame] = []
        self._token_watchers: list[TokenWatcher] = []
        self._apply(self.bridge.start(0), 0)

    @property
    def t_ns(self) -> int:
        """The simulated time reached [ns]."""
        return self._t

    def subscribe(self, suffix: str, handler: Handler) -> None:
        """Call ``handler`` with every message published on ``suffix`` from now on."""
        self._subs.setdefault(suffix, []).append(handler)

    def attach(self, wiring: Wiring[C, Any], core: C) -> None:
        """Feed ``core`` as its live shell would: every input of ``wiring`` and the
        ``trace/<q>/request`` mirror of each of its queryables (the answer is published on
        ``trace/<q>/reply``), through :meth:`manus.wiring.Wiring.feed`."""
        for suffix in wiring.input_suffixes:
            self.subscribe(suffix, _fed(wiring, core, suffix))

    def attach_node(self, node: BusNode) -> None:
        """Put another PC-side node on the bus from now on."""
        self.nodes.append(node)

    def watch_tokens(self, watcher: TokenWatcher) -> None:
        """Call ``watcher`` whenever a liveliness token vanishes (:meth:`token_gone`)."""
        self._token_watchers.append(watcher)

    def token_gone(self, service: str) -> None:
        """The token ``alive/<service>`` vanishes now (its process killed, a link cut): the
        bridge (unless stopped) and every watcher take it at once."""
        if not self._bridge_paused:
            self._apply(self.bridge.on_token_gone(service, self._t), self._t)
        for watcher in self._token_watchers:
            for suffix, msg in watcher(service, self._t):
                self._publish(suffix, msg, self._t)

    def pause_bridge(self, *, kill: bool = False) -> None:
        """The bridge stops (SIGSTOP; ``kill``: SIGKILL): it gets nothing and sends nothing."""
        self._bridge_paused = True
        self._bridge_killed = self._bridge_killed or kill

    def resume_bridge(self) -> None:
        """SIGCONT: the bridge gets every frame that waited, now, in order."""
        if self._bridge_killed:
            raise ValueError("the bridge was killed: it cannot resume")
        self._bridge_paused = False
        backlog, self._bridge_backlog = self._bridge_backlog, []
        for frame in backlog:
            self._apply(self.bridge.on_frame(frame, self._t), self._t)

    def restart_bridge(self, config: BridgeConfig | None = None) -> None:
        """A new bridge process takes over now (after a kill): a fresh core, started."""
        self.bridge = BridgeCore(config or self.bridge.config)
        self._bridge_paused = self._bridge_killed = False
        self._bridge_backlog = []
        self._apply(self.bridge.start(self._t), self._t)

    def bridge_input(self, frame: Frame) -> None:
        """A frame reaches the bridge now and only the bridge (a corrupted arm frame)."""
        self._bridge_frame(frame.at(self._t))

    def publish(self, suffix: str, msg: Message) -> None:
        """Publish ``msg`` now; it is delivered ``bus_latency_ns`` later."""
        self._publish(suffix, msg, self._t)

    def arm_command(self, cmd: ArmCommand) -> ArmCommandReply:
        """Ask the bridge (the ``bridge/command`` queryable), now."""
        reply: ArmCommandReply
        reply, out = BRIDGE.answer(ep.BRIDGE_COMMAND).handle(self.bridge, cmd, self._t)
        self._apply(out, self._t)
        return reply

    def run_until(self, t_ns: int) -> None:
        """Run every event up to and including ``t_ns``.

        Raises:
            ValueError: ``t_ns`` is in the past.
        """
        if t_ns < self._t:
            raise ValueError(f"run_until {t_ns} ns: time is already {self._t} ns")
        while True:
            t_sim = self.sim.next_event_ns()
            t_msg = self._queue[0][0] if self._queue else None
            due = [x for n in self.nodes if (x := n.next_event_ns()) is not None]
            t_node = min(due, default=None)
            t = min(x for x in (t_sim, t_msg, self._next_tick, t_node) if x is not None)
            if t > t_ns:
                break
            self._t = t
            if t == t_sim:
                self._sim_events(t)
            elif t == t_msg:
                item = heapq.heappop(self._queue)[2]
                if isinstance(item, _FrameTo):
                    self._frame_to(item)
                else:
                    self._deliver(item, t)
            elif t == t_node:
                self._node_events(t)
            else:
                if not self._bridge_paused:
                    self._apply(self.bridge.on_tick(t), t)
                self._next_tick += TICK_NS
        self.sim.advance(t_ns)
        self._t = t_ns

    def run_for(self, seconds: float) -> None:
        """Run ``seconds`` of simulated time from now."""
        self.run_until(self._t + round(seconds * 1e9))

    def run_until_phase(self, phase: str, timeout_s: float = 10.0) -> None:
        """Run until the bridge is in ``phase`` (checked every 10 ms of simulated time).

        Raises:
            TimeoutError: naming the phase wanted and the phase (and detail) seen.
        """
        end = self._t + round(timeout_s * 1e9)
        while self.bridge.phase != phase:
            if self._t >= end:
                raise TimeoutError(
                    f"bridge phase {phase!r} not reached within {timeout_s:g} s of simulated "
                    f"time: phase {self.bridge.phase!r} ({self.bridge.detail})"
                )
            self.run_until(min(end, self._t + 10_000_000))

    def published(self, suffix: str) -> list[Message]:
        """Every message published on ``suffix`` so far, in order."""
        return [m for _, s, m in self.messages if s == suffix]

    # -- plumbing -------------------------------------------------------------------------

    def _sim_events(self, t: int) -> None:
        for frame in self.sim.advance(t):
            self.arm_frames.append(frame)
            for node in self.nodes:
                node.receive(frame)
            self._bridge_frame(frame)
        for at, suffix, msg in self.sim.take_messages():
            self._publish(suffix, msg, at)

    def _bridge_frame(self, frame: Frame) -> None:
        if self._bridge_killed:
            return
        if self._bridge_paused:
            self._bridge_backlog.append(frame)
            return
        self._apply(self.bridge.on_frame(frame, frame.t_ns), frame.t_ns)

    def _node_events(self, t: int) -> None:
        for node in self.nodes:
            due = node.next_event_ns()
            if due is None or due > t:
                continue
            for frame in node.advance(t):
                self.node_frames.append(frame.at(t))
                arrival = frame.at(t + self.reply_latency_ns)
                self.sim.receive(arrival)
                for other in [None, *self.nodes]:
                    if other is not node:
                        item = _FrameTo(other, arrival)
                        heapq.heappush(self._queue, (arrival.t_ns, next(self._order), item))

    def _frame_to(self, item: _FrameTo) -> None:
        if item.node is None:
            self._bridge_frame(item.frame)
        else:
            item.node.receive(item.frame)

    def _apply(self, out: Outputs, now_ns: int) -> None:
        for frame in out.frames:
            self.bridge_frames.append(frame.at(now_ns))
            self.sim.receive(frame.at(now_ns + self.reply_latency_ns))
            arrival = frame.at(now_ns + self.reply_latency_ns)
            for node in self.nodes:
                item = _FrameTo(node, arrival)
                heapq.heappush(self._queue, (arrival.t_ns, next(self._order), item))
        for suffix, msg in BRIDGE.published(out):
            self._publish(suffix, msg, now_ns)

    def _publish(self, suffix: str, msg: Message, now_ns: int) -> None:
        self.messages.append((now_ns, suffix, msg))
        if suffix in self._subs or BRIDGE.input(suffix) is not None:
            due = now_ns + self.bus_latency_ns
            heapq.heappush(self._queue, (due, next(self._order), _Delivery(suffix, msg)))

    def _deliver(self, d: _Delivery, t: int) -> None:
        bridge_input = BRIDGE.input(d.suffix)
        if bridge_input is not None and not self._bridge_paused:  # a stopped bridge takes none
            self._apply(bridge_input.handle(self.bridge, d.msg, t), t)
        for handler in self._subs.get(d.suffix, ()):
            for suffix, msg in handler(d.msg, t):
                self._publish(suffix, msg, t)


def _fed(wiring: Wiring[C, Any], core: C, suffix: str) -> Handler:
    def handle(msg: Message, t_ns: int) -> list[tuple[str, Message]]:
        return wiring.feed(core, suffix, msg, t_ns)

    return handle
