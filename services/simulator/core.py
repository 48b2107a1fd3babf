"""The simulated Manus electronics: a deterministic core driven by a simulated clock.

The timeline (docs/architecture.md, Time): cycle k starts at T = 60 k ms; at T+20 one
snapshot of every position is taken and 0x350 sent, at T+40 0x360 from the same
snapshot, at T+60 the 0x37F sync (remote, DLC 0). The first reply received in
[T+60, T+80) is latched and becomes active at the tick T+80; later replies of the same
window and frames outside any window are ignored and counted. A move stays active until
another reply replaces it (a late or missing reply repeats the last command); a fold
(0x375/0x376) advances only in the cycles after a sync that it answered.

Every 20 ms tick integrates the active command over the tick that ends there
(:mod:`services.simulator.arm`), then moves the objects (:mod:`.object_world`: held,
falling, resting, their contacts). Events at the same instant run in this order: the
tick's integration, the arm's own event of that instant (activation and snapshot, 0x360,
or sync), frames leaving, frames from the PC, then the sensors (:mod:`.sensors`: the
camera, the target's tracker); :meth:`SimCore.take_messages` hands out what they publish.

The core never reads a clock and draws every random number from generators seeded by
``config.seed``: same configuration and inputs, same frames, bit for bit.
"""

from __future__ import annotations

import dataclasses
import heapq
import itertools

import numpy as np

from manus.errors import ManusError
from manus.protocol import (
    GEN_ANGLES_MEASURED,
    GEN_GRIPPER_READY,
    TICK_S,
    Frame,
    FrameId,
    Mode,
    MoveCommand,
    sync_frame,
)
from manus.scene import scene_from_setting
from schemas.base import Message
from schemas.state import SimTruth
from services.simulator import sensors
from services.simulator.arm import ArmModel, ArmState, Intent
from services.simulator.arm_faults import ArmFaults
from services.simulator.camera import Camera
from services.simulator.cartesian import cartesian_fields
from services.simulator.config import MS, SimConfig
from services.simulator.controller import ArmController, FoldProcedure
from services.simulator.counters import SimCounters
from services.simulator.faults import (
    Fault,
    FrameFault,
    FrameFaulter,
    Silence,
)
from services.simulator.messages import MessageBoard
from services.simulator.object_contacts import CONTACT_DEPTH
from services.simulator.object_world import ObjectWorld
from services.simulator.objects import SimObject
from services.simulator.rays import Primitive
from services.simulator.replies import WARN_CLAMPED, Reply, classify
from services.simulator.report import (
    Snapshot,
    garbage_fields,
    gripper_field,
    joint_fields,
)
from services.simulator.target import MovingTarget
from services.simulator.truth import ContactRecord, make_truth

TICK_NS = 20 * MS
"""The 20 ms tick [ns]."""
WINDOW_NS = 20 * MS
"""Length of the reply window after each sync [ns]."""

__all__ = ["MS", "TICK_NS", "WINDOW_NS", "SimCore", "SimError"]


class SimError(ManusError, ValueError):
    """The simulator core was driven against its contract (time going backwards...)."""


class SimCore:
    """The Manus electronics, stepped by :meth:`advance`; see the module docstring.

    Args:
        config: the simulator configuration (faults included).
    """

    def __init__(self, config: SimConfig | None = None) -> None:
        self.config = config or SimConfig()
        cfg = self.config
        rngs = np.random.default_rng(cfg.seed).spawn(5)
        model_rng, fault_rng, self._garbage_rng, camera_rng, target_rng = rngs
        gains = 1.0 + model_rng.uniform(-cfg.speed_gain_error, cfg.speed_gain_error, 6)
        self.model = ArmModel(cfg, gains)
        self.counters = SimCounters()
        self._faulter = FrameFaulter(fault_rng, self.counters)
        self._board = MessageBoard()
        self._board.post_general(round(cfg.gripper_ready_ms * MS), GEN_GRIPPER_READY)
        self._board.post_general(round(cfg.angles_measured_ms * MS), GEN_ANGLES_MEASURED)
        self._ready_ns = round(cfg.angles_measured_ms * MS)
        self._state: ArmState = self.model.initial_state()
        self._now = 0
        self._next_tick = TICK_NS
        self._order = itertools.count()
        self._outbox: list[tuple[int, int, Frame]] = []
        self._inbox: list[tuple[int, int, Frame]] = []
        self.controller = ArmController(cfg)
        """Mode, active command, fold procedure (:mod:`services.simulator.controller`)."""
        self._pending: Reply | None = None
        self._window: tuple[int, int] | None = None
        self._window_used = False
        self.snapshot: Snapshot | None = None
        """The last cycle's report."""
        self.contact_record = ContactRecord()
        """Contacts and the smallest true clearance since power-up (the truth reports them)."""
        self._arm_faults = ArmFaults()
        for fault in cfg.faults.all:
            self.add_fault(fault)
        scene = scene_from_setting(cfg.scene)
        self.objects = ObjectWorld(cfg, scene)
        """The objects: resting, held, falling (:mod:`services.simulator.object_world`)."""
        self.model.held, self.model.held_touch = self.objects.held_distance, CONTACT_DEPTH
        self.camera = Camera(cfg.camera, camera_rng, scene) if cfg.camera.enabled else None
        """The simulated camera (None: switched off)."""
        self.target: MovingTarget | None = None
        """The moving target and its tracker (None: switched off)."""
        if cfg.target.enabled:
            self.target = MovingTarget(cfg.target, target_rng, scene)
        self._messages: list[tuple[int, str, Message]] = []

    # -- the harness interface -----------------------------------------------------------

    @property
    def time_ns(self) -> int:
        """Simulated time reached by the last :meth:`advance` [ns]."""
        return self._now

    def next_event_ns(self) -> int:
        """Time of the next thing the core does: a tick, a frame leaving, a sensor's [ns]."""
        due = sensors.next_event_ns(self.camera, self.target)
        t = self._next_tick if due is None else min(self._next_tick, due)
        if self._outbox:
            return min(t, self._outbox[0][0])
        return t

    def advance(self, t_ns: int) -> list[Frame]:
        """Run every tick and frame up to and including ``t_ns``.

        Returns:
            the frames sent, in time order, each stamped with its send time.

        Raises:
            SimError: ``t_ns`` is before the current time.
        """
        if t_ns < self._now:
            raise SimError(f"advance to {t_ns} ns: time is already {self._now} ns")
        sent: list[Frame] = []
        while True:
            t_out = self._outbox[0][0] if self._outbox else None
            t_in = self._inbox[0][0] if self._inbox else None
            t_sensor = sensors.next_event_ns(self.camera, self.target)
            t = min(x for x in (self._next_tick, t_out, t_in, t_sensor) if x is not None)
            if t > t_ns:
                break
            self._now = t
            if t == self._next_tick:
                self._tick(t)
                self._next_tick += TICK_NS
            elif t == t_out:
                sent.append(heapq.heappop(self._outbox)[2])
            elif t == t_in:
                self._handle(heapq.heappop(self._inbox)[2])
            else:
                self._messages += sensors.event(self.camera, self.target, t, self._seen)
        self._now = t_ns
        self.counters.frames_sent += len(sent)
        return sent

    def receive(self, frame: Frame) -> None:
        """A frame from the PC; ``frame.t_ns`` is its arrival time.

        Raises:
            SimError: the frame arrived before the current time.
        """
        if frame.t_ns < self._now:
            raise SimError(
                f"frame 0x{frame.id:03X} arrives at {frame.t_ns} ns, before the current "
                f"time {self._now} ns"
            )
        if frame.t_ns == self._now:
            self._handle(frame)
        else:
            heapq.heappush(self._inbox, (frame.t_ns, next(self._order), frame))

    def truth(self, t_ns: int | None = None) -> SimTruth:
        """The true state at ``t_ns`` (default: now), between the last tick and the next.

        Raises:
            SimError: ``t_ns`` is outside [last tick, next tick].
        """
        t = self._now if t_ns is None else t_ns
        state = self.state_at(t)
        sensors.place_body(self.target, self.model.contacts, t)
        target = None if self.target is None else self.target.truth(t)
        return make_truth(
            self.model, state, t, t // TICK_NS, self.contact_record, self.objects, target
        )

    def take_messages(self) -> list[tuple[int, str, Message]]:
        """The bus messages the sensors published since the last call (:mod:`.sensors`):
        (publication time [ns], key suffix, message), in order."""
        out, self._messages = self._messages, []
        return out

    def state_at(self, t_ns: int) -> ArmState:
        """The mechanical state at ``t_ns`` in [last tick, next tick] (exact, not stored)."""
        last = self._next_tick - TICK_NS
        if not last <= t_ns <= self._next_tick:
            raise SimError(f"state at {t_ns} ns: only [{last}, {self._next_tick}] ns is known now")
        if t_ns == last:
            return self._state
        sensors.place_body(self.target, self.model.contacts, t_ns)
        return self.model.step(self._state, self._intent(last), (t_ns - last) / 1e9).state

    # -- run-time controls and readings -----------------------------------------------------

    def add_fault(self, fault: Fault) -> None:
        """Switch a fault on now (its own times still apply)."""
        if isinstance(fault, FrameFault | Silence):
            self._faulter.add(fault)
        else:
            self._arm_faults.add(fault)

    def clear_faults(self) -> None:
        """Switch every fault off (a latched error stays until a 0x370)."""
        self._faulter.clear()
        self._arm_faults.clear()

    @property
    def mode(self) -> Mode:
        """The mode nibble the arm reports."""
        return self.controller.mode

    @property
    def active(self) -> MoveCommand | None:
        """The latched move being executed (None: stopped, or a fold)."""
        return self.controller.active

    @property
    def fold(self) -> FoldProcedure | None:
        """The fold procedure in progress or completed, if any."""
        return self.controller.fold

    @property
    def state(self) -> ArmState:
        """The mechanical state at the last tick."""
        return self._state

    @property
    def error(self) -> int | None:
        """The latched error code, if any."""
        return self._board.error

    def encoder_counts(self) -> tuple[int, ...]:
        """What the encoders read at the last tick: motors 1..6 [0.1 deg], gripper [0.1 mm].

        These are the real readings, before the report's garbage or stale substitutions.
        """
        return (*joint_fields(self._state.motor_deg, None), gripper_field(self._state.gripper_mm))

    # -- the timeline --------------------------------------------------------------------

    def _tick(self, t: int) -> None:
        sensors.place_body(self.target, self.model.contacts, t)
        result = self.model.step(self._state, self._intent(t - TICK_NS), TICK_S)
        self._state = result.state
        if self.objects.objects:
            if result.contact:
                self.objects.blocked(t, result.contact)
            self._move_objects(t)
        self.contact_record.update(result)
        self._board.raise_warnings(result.warnings)
        ctl = self.controller
        if ctl.active is not None and ctl.active_clamped:
            self._board.raise_warnings({WARN_CLAMPED})
        fold = ctl.fold
        if result.arrived and fold is not None and not fold.done:
            fold.done = True
            self._board.post_general(t, fold.done_message)
        self._timed_faults(t)
        phase = (t // TICK_NS) % 3
        if phase == 1:
            self._window = None
            self._activate(t)
            self._take_snapshot(t)
            assert self.snapshot is not None
            self._emit(self.snapshot.status_frame())
        elif phase == 2 and self.snapshot is not None:
            self._emit(self.snapshot.position_frame(t))
        elif phase == 0:
            self._emit(sync_frame(t))
            self._window = (t, t + WINDOW_NS)
            self._window_used = False

    def _move_objects(self, t: int) -> None:
        state = self._state
        self.objects.tick(t, self.model.q_true_deg(state), state.gripper_mm)
        floor = self.objects.gripper_floor_mm
        if floor > state.gripper_mm:  # the jaws closed on an object this tick: they stop there
            self._state = dataclasses.replace(state, gripper_mm=floor, gripper_speed_mm_s=0.0)

    def _seen(self, t: int) -> tuple[list[tuple[SimObject, np.ndarray]], list[Primitive]]:
        """What the camera sees at ``t``: the objects at their poses, the arm's bodies."""
        state = self.state_at(t)
        bodies, poses = self.objects.placed(t, self.model.q_true_deg(state), state.gripper_mm)
        arm = [Primitive(b.shape, b.size, b.pose) for b in bodies]
        return list(zip(self.objects.objects, poses, strict=True)), arm

    def _timed_faults(self, t: int) -> None:
        for code in self._arm_faults.errors_due(t):
            self._board.latch_error(code)
            self.controller.halt()
        self._board.raise_warnings(self._arm_faults.warnings_at(t))

    def _emit(self, frame: Frame) -> None:
        for out in self._faulter.apply(frame):
            heapq.heappush(self._outbox, (out.t_ns, next(self._order), out))

    def _handle(self, frame: Frame) -> None:
        kind = classify(frame.id, frame.data, frame.remote, frame.dlc)
        if kind == "ack":
            self.counters.ack_frames += 1
            return
        if kind == "bad":
            self.counters.bad_frames += 1
            return
        if kind == "unknown":
            self.counters.unknown_frames += 1
            return
        assert isinstance(kind, Reply)
        window = self._window
        if window is None or not window[0] <= frame.t_ns < window[1]:
            self.counters.outside_window += 1
            return
        if self._window_used:
            self.counters.extra_replies += 1
            return
        if kind.kind != FrameId.STOP and frame.t_ns < self._ready_ns:
            self.counters.not_ready += 1
            return
        self._window_used = True
        self._pending = kind
        self.counters.replies_latched += 1
        if kind.clamped:
            self.counters.clamped += 1
            self._board.raise_warnings({WARN_CLAMPED})

    def _activate(self, t: int) -> None:
        reply, self._pending = self._pending, None
        error = self._board.error is not None
        outcome = self.controller.activate(reply, t, self._state.motor_deg, error=error)
        if outcome == "stop":
            self._board.clear_error()
        elif outcome == "ignored":
            self.counters.ignored_in_error += 1

    def _intent(self, t0: int) -> Intent:
        """What the drives do over the tick starting at ``t0``."""
        stuck = self._arm_faults.stuck_at(t0)
        error = self._board.error is not None
        intent = self.controller.intent(t0, self._state.motor_deg, stuck, error=error)
        floor = self.objects.gripper_floor_mm
        return intent if floor <= 0.0 else dataclasses.replace(intent, gripper_min_mm=floor)

    # -- the report ----------------------------------------------------------------------

    def _take_snapshot(self, t: int) -> None:
        msg_class, code = self._board.take(t)
        state = self._state
        ctl = self.controller
        if not ctl.positions_valid:
            values = garbage_fields(self._garbage_rng, self.config.garbage)
            fields, gripper = values[:6], values[6]
        else:
            gripper = gripper_field(state.gripper_mm)
            if ctl.mode == Mode.CARTESIAN:
                fields = cartesian_fields(state.motor_deg, self.config.arm)
            else:
                stale = ctl.stale_until_ns is None or t < ctl.stale_until_ns
                fields = joint_fields(
                    state.motor_deg, self.config.stale_encoders_deg if stale else None
                )
        f1, f2, f3, f4, f5, f6 = fields
        self.snapshot = Snapshot(
            t, int(ctl.mode), msg_class, code, (f1, f2, f3, f4, f5, f6), gripper
        )
