"""The controller's deterministic core: joint states in, one guarded command out per state.

Contract (docs/architecture.md, Time; Freshness and safety rules; Command sources):

- Every valid joint state is answered with exactly one ``cmd/joint_velocity`` command
  (``ref_seq`` = the state's ``seq``): the command of the source that holds the arm
  (:mod:`.command_source`; the registry :data:`.sources.SOURCES`: goals, the jog), put
  through the one collision guard (:mod:`.guard`); zeros when none holds it. Each source
  adds its reports (a goal's feedback, the jog's state) and its outcomes (goal results,
  each published once, stamped with the message being answered when it leaves).
- Sources are ranked: when one takes the arm, the engaged ones below it end (preempted,
  with the taker's cause: a moving jog ends every goal, ``user_took_over``); a request to
  a source while one above it holds the arm is refused (``busy``).
- Stops: an error reported by the arm stops every source with the arm's message, and so
  does the bridge leaving ``running`` (stop, e-stop, arm error, fold), an invalid state
  or a mode other than joint mode. A gap in the joint states (a ``seq`` jump or a stamp
  gap over ``max_stamp_gap_ms``) is answered with zeros (nothing is extrapolated) and the
  drives' estimates start afresh; a gap longer than ``max_outage_ms`` stops every source.
- A source stopped by a request of its own that stops at once (the jog released or
  refused), or whose goals the vanished liveliness token of their heartbeats' sender
  stops, has the command already sent for this cycle replaced by zeros.
- Time comes only from the messages' stamps; no clock, no randomness: replaying the same
  messages gives the same commands, bit for bit.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Callable
from typing import Any, TypeVar, cast

import numpy as np

from manus.joint_map import dh_increments_to_encoder_list, dh_to_encoder_list
from manus.scene import Scene, start_scene_state
from manus.world_follower import WorldFollower
from schemas import endpoints as ep
from schemas.base import Message
from schemas.collision import ClearanceReport, SceneState
from schemas.control import EndCause, QueryTaken, Refusal, ResultStatus
from schemas.liveliness import TokenGone
from schemas.objects import WorldUpdate
from schemas.state import ArmStatus, BridgeState, JointState
from services.controller.backlash import PlayModel
from services.controller.command_source import (
    Command,
    CommandSource,
    Cycle,
    End,
    Host,
    Refused,
    Sent,
)
from services.controller.config import MS, ControllerConfig
from services.controller.estimator import DriveEstimator
from services.controller.outbox import GoalOutcome, Outbox, Output
from services.controller.run_guard import run_guard, scene_guard
from services.controller.sources import SOURCES

__all__ = ["STOPPING_PHASES", "ControllerCore", "Output"]

S = TypeVar("S", bound=CommandSource)

STOPPING_PHASES = ("stopped", "estopped", "arm_error", "folding_in", "folding_out", "shutdown")
"""Bridge phases in which nothing may move: entering one stops every source."""

_STILL = (0.0,) * 6
"""The motors' speeds in flight when the frame in flight is not a joint move [rad/s]."""
_ZERO = np.zeros(6, dtype=np.int64)
_IDLE = Command(_ZERO, 0)

GRIPPER_UNIT_M = 1e-4
"""Resolution of the gripper reading [m] (0.1 mm)."""


class ControllerCore:
    """The command sources, the drives' estimates and the guard (see the module docstring).

    Args:
        config: controller settings.
    """

    def __init__(self, config: ControllerConfig | None = None) -> None:
        self._config = config or ControllerConfig()
        cfg = self._config
        tau = cfg.drive_tau_ms / 1000.0
        half = math.radians(cfg.encoder_unit_deg) / 2.0 if cfg.observer else 0.0
        self.joints = DriveEstimator(tau, half, 6)
        """Estimated motor angles [rad] and speeds."""
        self.play = PlayModel(
            np.radians(cfg.backlash_deg),
            math.radians(cfg.backlash_dead_zone_deg),
        )
        """Estimated belt outputs (default mode, when ``backlash_deg`` is set)."""
        self.grip = DriveEstimator(tau, GRIPPER_UNIT_M / 2.0, 1)
        """Estimated gripper opening [m] and speed."""
        self._last_js: JointState | None = None
        self.arm_error: str | None = None
        """The arm's error message while it reports one."""
        self.bridge_phase: str | None = None
        """The bridge's phase (None: no BridgeState seen, not checked)."""
        self.last_counts = np.zeros(6, dtype=np.int64)
        """Motor speed steps of the last command sent, shape (6,)."""
        self.outbox = Outbox()
        """Command numbering and the goal results waiting to leave."""
        self.guard = run_guard(cfg.scene, cfg.arm)
        """The collision guard every command passes (None: no scene)."""
        self.scene_seen = start_scene_state(cfg.scene)
        """The scene the guard keeps clear of, as the planner announces it (``cfg.scene``'s
        until the planner's differs; None: no scene)."""
        self.world = WorldFollower()
        """The world model as the planner publishes it: the objects the arm holds, which
        the guard keeps clear like the arm's own bodies."""
        self.moved: dict[str, np.ndarray] = {}
        """Scene objects a tracker moved (name -> pose, chair frame), kept across scenes."""
        # A weak reference, no cycle: a core let go of frees its guard's model at once.
        self.sources = tuple(kind(cast(Host, weakref.proxy(self))) for kind in SOURCES)
        """One of each registered command source."""
        self._ranked = sorted(self.sources, key=lambda s: -s.PRIORITY)
        self._observers = [s for s in self.sources if type(s).observe is not CommandSource.observe]

    # -- what a source may ask (services.controller.command_source.Host) -----------------

    @property
    def config(self) -> ControllerConfig:
        """The controller's settings."""
        return self._config

    @property
    def last_js(self) -> JointState | None:
        """The newest joint state (None: none yet)."""
        return self._last_js

    def admission(self, source: CommandSource) -> Refused | None:
        """Why a request of ``source`` is refused now: a source above it holds the arm,
        or nothing may move (None: it may take the arm; the guard prepares its checks)."""
        above = next((s for s in self._ranked if s.PRIORITY > source.PRIORITY and s.engaged), None)
        if above is not None:
            return Refused(Refusal.BUSY, above.BUSY, above.KIND)
        reason = self._not_ready()
        if reason is None and self.guard is not None and self._last_js is not None:
            self.guard.prepare(self._last_js)  # not in the first command's cycle
        transient = self.bridge_phase == "resync" and self.arm_error is None
        return None if reason is None else Refused(Refusal.NOT_READY, reason, transient=transient)

    def finish(self, outcome: GoalOutcome) -> None:
        """A goal ended: its result leaves with the next publication."""
        self.outbox.queue(outcome)

    def clearance(self, goal_id: str) -> ClearanceReport | None:
        """The smallest clearance the guard computed for ``goal_id`` (forgotten once read)."""
        return self.guard.result(goal_id) if self.guard is not None else None

    @property
    def scene(self) -> Scene | None:
        """The scene the collision guard keeps clear of (None: none)."""
        return self.guard.guard.model.scene if self.guard is not None else None

    def move_object(self, name: str, pose: np.ndarray) -> None:
        """Place the scene object ``name`` at ``pose`` (4x4, chair frame) in the guard, now
        and in every scene that replaces this one.

        Raises:
            SceneError: no such object.
        """
        if self.guard is not None:
            self.guard.move_object(name, pose)
        self.moved[name] = pose

    def source(self, kind: type[S]) -> S:
        """The source of class ``kind``.

        Raises:
            KeyError: no such source is registered.
        """
        for s in self.sources:
            if isinstance(s, kind):
                return s
        raise KeyError(f"no command source {kind.__name__} in services.controller.sources")

    # -- the sources' inputs (the wiring map's rows, services.controller.wiring) ----------

    def take(self, kind: type[S], handle: Callable[[S, Any], Output], msg: Any) -> Output:
        """A publication for source ``kind``: its outputs; the sources below it preempted
        if it took the arm; zeros now if it stopped at once; the results so far, with
        anything it publishes (results leave with the controller's next publication)."""
        source = self.source(kind)
        was = source.engaged
        out = handle(source, msg)
        self._preempt_below(source)
        js = self._last_js
        if js is None or not out:
            return out
        if was and source.STOPS_AT_ONCE and not source.engaged:
            out.append(self._zeros_now(js))
        return out + self.outbox.flush(js.stamp_ns)

    def ask(
        self, kind: type[S], handle: Callable[[S, Any], Message], query: str, request: Any
    ) -> tuple[Message, Output]:
        """A query on ``query`` for source ``kind``: its reply (results leave with the next
        joint state) and where it was taken (:class:`~schemas.control.QueryTaken`)."""
        js = self._last_js
        taken = QueryTaken(query=query, after_seq=-1 if js is None else js.seq)
        source = self.source(kind)
        reply = handle(source, request)
        self._preempt_below(source)
        return reply, [(ep.QUERY_TAKEN, taken)]

    def _preempt_below(self, source: CommandSource) -> None:
        end = source.preemption()
        if end is None:
            return
        for other in self._ranked:
            if other.PRIORITY < source.PRIORITY and other.engaged:
                other.stop(end)

    def _zeros_now(self, js: JointState) -> tuple[str, Message]:
        """Zeros replacing the command already sent for ``js`` (at the next sync)."""
        self.last_counts = np.zeros(6, dtype=np.int64)
        return ep.JOINT_VELOCITY, self.outbox.command(js, self.last_counts, 0)

    # -- the arm ---------------------------------------------------------------------------

    def on_status(self, st: ArmStatus) -> Output:
        """An error from the arm stops every source (the commands drop to zero)."""
        if st.msg_class != "error":
            self.arm_error = None
            return []
        first = self.arm_error is None
        self.arm_error = st.text or f"arm error code {st.msg_code}"
        if first:
            self._stop_all(EndCause.ARM_ERROR, f"arm error: {self.arm_error}")
        return self.outbox.flush(st.stamp_ns)

    def on_bridge_state(self, bs: BridgeState) -> Output:
        """Follow the bridge's phase: sources run only while it is ``running``.

        Leaving ``running`` for a stop, an e-stop, an arm error, a fold or a shutdown
        stops every source (``resync`` does not: it shows as a gap in the joint states).
        """
        self.bridge_phase = bs.phase
        if bs.phase in STOPPING_PHASES and any(s.engaged for s in self.sources):
            self._stop_all(EndCause.BRIDGE_PHASE, f"bridge phase {bs.phase}: {bs.detail}")
            return self.outbox.flush(bs.stamp_ns)
        return []

    def on_scene(self, scene: SceneState) -> Output:
        """The planner's scene (replaced at run time, or its periodic announcement): the
        guard follows it (one that does not build keeps the guard as it was; the planner
        validated it already). The same scene again, or no guard at all: nothing."""
        if scene.same_scene(self.scene_seen):
            return []
        self.scene_seen = scene
        guard = self.guard and scene_guard(scene, self._config.arm, self.world.held, self.moved)
        if guard is not None:
            self.guard = guard
        return []

    def on_objects(self, update: WorldUpdate) -> Output:
        """The world model's updates (``planner/objects``): the guard keeps an object the
        arm holds (attached to the gripper) clear like a link of the arm, from the next
        command on. Never publishes."""
        if self.world.on_update(update) and self.guard is not None:
            self.guard.hold(self.world.held)
        return []

    def on_token_gone(self, service: str) -> Output:
        """The token ``alive/<service>`` vanished (its process died or its link was cut).

        A source tied to it (goals whose heartbeats came from it) stops at once, and a zero
        command replaces the one already sent for this cycle. Always published as a
        :class:`~schemas.liveliness.TokenGone` (after which joint state it came: the
        regression check feeds it there).
        """
        js = self._last_js
        reason = ""
        for source in self.sources:
            reason = source.token_gone(service) or reason
        record = TokenGone(service=service, after_seq=-1 if js is None else js.seq, stopped=reason)
        out: Output = [(ep.TOKEN_GONE, record)]
        if js is None:
            return out
        if reason:
            out.append(self._zeros_now(js))
        return out + self.outbox.flush(js.stamp_ns)

    def _not_ready(self) -> str | None:
        """Why nothing may move now (None: it may)."""
        if self.arm_error is not None:
            return f"the arm reports an error: {self.arm_error}"
        if self.bridge_phase is not None and self.bridge_phase != "running":
            return (
                f"the bridge is in phase {self.bridge_phase!r}, not 'running' "
                "(clear it or wait for it first)"
            )
        return None

    def _stop_all(self, cause: EndCause, reason: str) -> None:
        end = End(ResultStatus.ABORTED, cause, reason)
        for source in self.sources:
            source.stop(end)

    # -- the cycle -------------------------------------------------------------------------

    def on_joint_state(self, js: JointState) -> Output:
        """One cycle: the command for this joint state, the sources' reports, results."""
        last = self._last_js
        if last is not None and js.seq <= last.seq and js.stamp_ns <= last.stamp_ns:
            return []  # a duplicate or an old state: already answered
        # A lower seq with a newer stamp is a restarted bridge (its seq starts again at 0):
        # a gap, answered.
        cfg = self._config
        gap = last is not None and (
            js.seq != last.seq + 1 or js.stamp_ns - last.stamp_ns > cfg.max_stamp_gap_ns
        )
        self._last_js = js
        for source in self._observers:  # (the others do nothing there: no call per cycle)
            source.observe(js, last)
        usable = js.valid and js.mode == "joint"
        if gap or not usable:
            self._interrupted(js, last, gap, usable)
        if not usable:
            return self._answer(js, _IDLE, None)
        position = [float(v) for v in js.position]
        self._estimate(js, position, 0.0 if last is None or gap else js.stamp_ns - last.stamp_ns)
        if self.arm_error is not None:
            return self._answer(js, _IDLE, None)
        snap = js.stamp_ns - cfg.snapshot_age_ns
        q = np.array(position)
        cycle = Cycle(
            js, snap, q, position, gap, self.joints, self.grip, self.play, self.last_counts
        )
        for source in self._ranked:
            command = source.command(cycle)
            if command is not None:
                return self._answer(js, command, source)
        return self._answer(js, _IDLE, None)

    def _interrupted(
        self, js: JointState, last: JointState | None, gap: bool, usable: bool
    ) -> None:
        """A gap in the joint states or an unusable one: the estimates start afresh; a long
        outage or an unusable state stops every source."""
        cfg = self._config
        self.joints.reset()
        self.grip.reset()
        self.play.reset()
        if gap and last is not None and self._outage(js, last) > cfg.max_outage_ms * MS:
            self._stop_all(
                EndCause.STATES_INTERRUPTED,
                f"joint states interrupted: seq {js.seq} after {last.seq}, "
                f"{(js.stamp_ns - last.stamp_ns) / 1e6:.0f} ms apart, more than "
                f"max_outage_ms {cfg.max_outage_ms:g} ms (stopped)",
            )
        if not usable:
            self._stop_all(
                EndCause.STATE_UNUSABLE,
                f"joint state not usable (valid={js.valid}, mode {js.mode})",
            )

    def _estimate(self, js: JointState, position: list[float], dt_ns: int | float) -> None:
        """Update the motor, belt and gripper estimates with this snapshot and the
        speeds in flight (``dt_ns``: time since the last state, 0 after a gap).

        The drives are modelled where they are, per motor (:mod:`.estimator`: each motor's
        speed lag, each encoder's 0.1 deg cell): the DH angles and velocities go through
        the joint map into motor coordinates here, in SI (rad, rad/s)."""
        dt = dt_ns / 1e9
        joint = js.applied_kind == "joint"
        rates = dh_increments_to_encoder_list(js.applied_velocity) if joint else _STILL
        motors = self.joints.update(dh_to_encoder_list(position), rates, dt)
        if self.play.active:
            self.play.update(np.array(motors))
        self.grip.update([js.gripper], [js.applied_gripper_velocity if joint else 0.0], dt)

    def _outage(self, js: JointState, last: JointState) -> int:
        """How long the joint states were missing [ns] (0: none)."""
        cycle = self._config.cycle_ns
        by_stamp = js.stamp_ns - last.stamp_ns - cycle
        by_seq = (js.seq - last.seq - 1) * cycle
        return max(0, by_stamp, by_seq)

    def _answer(self, js: JointState, command: Command, source: CommandSource | None) -> Output:
        """The pipeline's end: the guard, the command, every source's reports, results."""
        counts = np.asarray(command.counts, dtype=np.int64)
        guarded = ""
        if self.guard is not None and js.valid:
            verdict = self.guard.command(js, counts, command.goal_id)
            counts, guarded = verdict.counts, verdict.reason
            if source is not None and verdict.scale < 1.0:
                source.guarded(command, verdict)
        self.last_counts = counts
        cmd = self.outbox.command(js, counts, command.grip)
        out: Output = [(ep.JOINT_VELOCITY, cmd)]
        sent = Sent(js, cmd, guarded)
        for s in self.sources:
            out += s.reports(sent)
        return out + self.outbox.flush(js.stamp_ns)
