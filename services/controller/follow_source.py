"""Following a moving target as a command source (docs/follow.md).

:class:`FollowSource` takes every tracker's frames (``target/pose``: each published at
once as a ``TargetTaken``, after which joint state it came, for exact replays) and the
follow goals (``controller/follow``). A goal starts at the next joint state: its tracked
point follows the target of its ``source`` to the standoff point and holds it there
(:mod:`.follow_law`; the target's prediction over the delays: :mod:`.target_track`;
the scene's persons, zones and reach: :mod:`.follow_space`; the goal's checks:
:mod:`.follow_goal`; the bodies the frames report: :mod:`.follow_body`), until it is
stopped (a
``stop`` request: cancelled), preempted (a jog: ``user_took_over``; a new follow goal:
``new_goal``) or a fault ends it. It ranks above trajectory goals (it preempts them) and
below the jog.

**Faults** end the goal, and the command of the joint state that finds one is zeros (one
found by a frame between two joint states replaces the command already sent for the
cycle): the target lost (no newer frame for ``lost_after`` beyond its latency, or the
tracker says so), a jump (the target moving faster than a person can, or its body
reported beyond ``max_body_shift_m`` of its place in the scene), the standoff point out
of reach, in a keep-out zone, or behind a singularity. Nothing resumes by itself: only a
new goal moves the arm again.

**The person moves**: a frame that carries the pose of the body its target moves with
(``TargetPose.body``: the user's ``head``) places that scene object there in the
collision guard (:meth:`~.command_source.Host.move_object`) at the next joint state,
before its command is guarded, whether a goal runs or not, within ``max_body_shift_m`` of
its place in the scene; the guard keeps that pose until a newer frame moves it (in every
scene that replaces this one too).
"""

from __future__ import annotations

import numpy as np

from manus.kinematics import gripper_pose
from schemas import endpoints as ep
from schemas.control import CommandSourceKind, EndCause, GoalAck, GoalKind, Refusal, ResultStatus
from schemas.follow import FollowGoal
from schemas.state import JointState
from schemas.target import TargetPose, TargetTaken
from services.controller.command_source import (
    Command,
    CommandSource,
    Cycle,
    End,
    Host,
    Refused,
    Sent,
    SourceAnswer,
    SourceInput,
)
from services.controller.follow_body import Bodies, rotation
from services.controller.follow_goal import FollowError, settings
from services.controller.follow_law import Aim, FollowRun, Settings, follow_counts
from services.controller.follow_report import FollowReport
from services.controller.follow_space import FollowSpace
from services.controller.guard import Verdict
from services.controller.jog_law import predicted_dh
from services.controller.jog_state import guard_limit
from services.controller.outbox import GoalOutcome, Output
from services.controller.target_track import Frame, TargetTrack

_ZERO = np.zeros(6, dtype=np.int64)
_SOURCES_KEPT = 8
"""Trackers whose frames are kept (the oldest heard of is forgotten beyond)."""


def _ack(goal_id: str, refused: Refused | None = None) -> GoalAck:
    if refused is None:
        return GoalAck(accepted=True, goal_id=goal_id)
    return GoalAck(
        accepted=False,
        goal_id=goal_id,
        reason=refused.reason,
        refusal=refused.refusal,
        held_by=refused.held_by,
    )


class FollowSource(CommandSource):
    """Follow goals and the trackers' frames (see the module docstring)."""

    KIND = CommandSourceKind.FOLLOW
    PRIORITY = 5
    STOPS_AT_ONCE = True
    BUSY = "the arm follows a target (controller/follow_state): goals wait until it ends"

    def __init__(self, host: Host) -> None:
        super().__init__(host)
        self.config = host.config
        self.tracks: dict[str, TargetTrack] = {}
        """Each tracker's newest frames, by ``source``."""
        self.frames_of: dict[str, TargetPose] = {}
        """Each tracker's newest frame as received."""
        self.pending: FollowGoal | None = None
        """The goal that starts at the next joint state."""
        self.goal: FollowGoal | None = None
        """The goal running."""
        self.run: FollowRun | None = None
        self.started_ns = 0
        self.report = FollowReport()
        self._space: tuple[object, FollowSpace] | None = None
        self.refused: dict[str, int] = {}
        """Frames refused per tracker (not decodable: under '')."""
        self.bodies = Bodies(self.config.follow.max_body_shift_m)
        """The person bodies the frames report, placed at the next joint state."""

    @property
    def engaged(self) -> bool:
        return self.pending is not None or self.goal is not None

    @property
    def space(self) -> FollowSpace:
        """The scene as the follow law sees it, built again when the guard's scene changes."""
        scene = self.host.scene
        if self._space is None or self._space[0] is not scene:
            space = FollowSpace(scene, self.config.arm)
            for name, pose in self.report.bodies.items():
                space.move_person(name, pose)
            self._space = (scene, space)
        return self._space[1]

    # -- the trackers' frames ----------------------------------------------------------------

    def on_target(self, msg: TargetPose) -> Output:
        """A tracker's frame: kept, its body placed, a jump or a loss noted."""
        js = self.host.last_js
        after = -1 if js is None else js.seq
        taken: Output = [(ep.TARGET_TAKEN, TargetTaken(after_seq=after, target=msg))]
        space = self.space
        if msg.frame == "chair" and not space.has_scene:
            self.refused[msg.source] = self.refused.get(msg.source, 0) + 1
            return taken
        following = self.goal is not None and self.goal.source == msg.source
        if not msg.tracked:
            if following:
                self._fault(EndCause.TARGET_LOST, f"the tracker {msg.source!r} lost the target")
            return taken
        track = self._track(msg.source)
        jump = track.add(Frame(msg.stamp_ns, space.point_to_base(msg.xyz, msg.frame)))
        self.frames_of[msg.source] = msg
        if following:
            self.report.frames += 1
        if jump is not None and following:
            self._fault(
                EndCause.TARGET_JUMP,
                f"the target {msg.source!r} moved {jump.distance * 1e3:.0f} mm in "
                f"{jump.interval * 1e3:.0f} ms, more than a person can "
                f"({jump.allowed * 1e3:.0f} mm at {track.max_speed:g} m/s plus the noise)",
            )
        why = self.bodies.take(msg, space, self.host.scene)
        if why is not None and following:
            self._fault(EndCause.TARGET_JUMP, why)
        return taken

    def on_bad_target(self, error: str) -> Output:
        """A target payload that does not decode: counted (under '')."""
        self.refused[""] = self.refused.get("", 0) + 1
        js = self.host.last_js
        after = -1 if js is None else js.seq
        return [(ep.TARGET_TAKEN, TargetTaken(after_seq=after, target=None, error=error))]

    # -- the goals ---------------------------------------------------------------------------

    def request(self, goal: FollowGoal) -> GoalAck:
        """Start a follow goal (at the next joint state) or stop one."""
        if goal.stop:
            return self._stop_request(goal.goal_id)
        try:
            self._settings(goal)
        except FollowError as exc:
            return _ack(goal.goal_id, Refused(Refusal.INVALID, str(exc)))
        refused = self.host.admission(self) or self._not_ready(goal)
        if refused is not None:
            return _ack(goal.goal_id, refused)
        new = End(ResultStatus.PREEMPTED, EndCause.NEW_GOAL, f"replaced by {goal.goal_id!r}")
        if self.pending is not None:
            self._finish(self.pending, new, 0)
        if self.goal is not None:
            self._end(new)
        self.pending = goal
        return _ack(goal.goal_id)

    INPUTS = (SourceInput(ep.TARGET, on_target, bad=on_bad_target),)
    ANSWERS = (SourceAnswer(ep.FOLLOW, request),)

    def preemption(self) -> End | None:
        """A follow goal ends the trajectory and gripper goals below it."""
        if self.pending is None:
            return None
        why = f"a follow goal took the arm ({self.pending.goal_id!r})"
        return End(ResultStatus.PREEMPTED, EndCause.NEW_GOAL, why)

    def stop(self, end: End) -> None:
        """Preempted by a source above it, or a fault of the arm: the goal ends."""
        if self.pending is not None:
            self._finish(self.pending, end, 0)
            self.pending = None
        if self.goal is not None:
            self._end(end)

    # -- the cycle ---------------------------------------------------------------------------

    def command(self, cycle: Cycle) -> Command | None:
        """This cycle's counts while a goal runs (zeros when it ends now)."""
        if self.pending is not None:
            self._begin(self.pending, cycle)
        goal, run = self.goal, self.run
        if goal is None or run is None:
            return None
        est, js = cycle.joints, cycle.js
        track = self.tracks[goal.source]
        age = track.observe(js.stamp_ns)
        lost = None if age is None else track.lost(age, goal.lost_after)
        if lost is not None:
            self._end(End(ResultStatus.ABORTED, EndCause.TARGET_LOST, f"{goal.source!r}: {lost}"))
            return Command(_ZERO, 0, goal.goal_id)
        if cycle.gap or est.x is None:  # nothing is known of the cycles missed: zeros
            return Command(_ZERO, 0, goal.goal_id)
        cfg = self.config
        q_pred = predicted_dh(est, cfg)
        run.anchor(q_pred, cfg)
        t_end = cycle.snap_ns + round((cfg.command_delay_ms + cfg.cycle_ms) * 1e6)
        aim = self._aim(goal, track, t_end)
        step = run.step(aim, self.space, cfg)
        self.report.cycle(step, aim, age or 0)
        if step.fault is not None:
            self._end(End(ResultStatus.ABORTED, step.fault.cause, step.fault.reason))
            return Command(_ZERO, 0, goal.goal_id)
        counts = follow_counts(step.q_target, est, cycle.play, cfg, holding=step.still)
        return Command(counts, 0, goal.goal_id)

    def guarded(self, command: Command, verdict: Verdict) -> None:
        """The collision guard slowed or stopped the motion: a limit in the state."""
        self.report.guard = guard_limit(verdict)

    def reports(self, sent: Sent) -> Output:
        """The FollowState every cycle while a goal runs, and once when it ends."""
        goal = self.goal or self.report.ended_goal
        if goal is None:
            return []
        point = self._point(sent.js.position, goal)
        hold = self.config.follow.hold_tolerance_m
        out = self.report.state(sent.js, goal, point, self.tracks.get(goal.source), hold)
        return [(ep.FOLLOW_STATE, out)]

    # -- internals ---------------------------------------------------------------------------

    def _track(self, source: str) -> TargetTrack:
        track = self.tracks.get(source)
        if track is None:
            if len(self.tracks) >= _SOURCES_KEPT:
                oldest = min(self.tracks, key=lambda s: self.tracks[s].frames[-1].stamp_ns)
                del self.tracks[oldest]
            track = self.tracks[source] = TargetTrack(self.config.follow)
        return track

    def _settings(self, goal: FollowGoal) -> Settings:
        """The goal's settings against the controller's (:func:`.follow_goal.settings`).

        Raises:
            FollowError: naming the field, the value and the limit.
        """
        newest = self.frames_of.get(goal.source)
        on_person = newest is None or bool(newest.body)  # no frame yet: as if on a person
        return settings(goal, self.config.follow, self.space.person_clearance, on_person)

    def _not_ready(self, goal: FollowGoal) -> Refused | None:
        """Why ``goal`` cannot start now: no joint state, no fresh frame of its target."""
        js = self.host.last_js
        if js is None or not js.valid:
            why = "no valid joint state yet (is the bridge running?)"
            return Refused(Refusal.NOT_READY, why)
        track = self.tracks.get(goal.source)
        newest = track.newest if track is not None else None
        if track is None or newest is None:
            why = f"no frame of the target {goal.source!r} on target/pose yet"
            return Refused(Refusal.NOT_READY, why)
        lost = track.lost(js.stamp_ns - newest.stamp_ns, goal.lost_after)
        if lost is not None:
            return Refused(Refusal.NOT_READY, f"the target {goal.source!r} is lost: {lost}")
        return None

    def _begin(self, goal: FollowGoal, cycle: Cycle) -> None:
        self.pending = None
        self.goal = goal
        self.tracks[goal.source].max_speed = goal.max_target_speed or (
            self.config.follow.max_target_speed
        )
        self.started_ns = cycle.js.stamp_ns
        self.report.begin(goal)
        q = predicted_dh(cycle.joints, self.config) if cycle.joints.x is not None else None
        start = q if q is not None else [float(v) for v in cycle.q]
        self.run = FollowRun.start(self._settings(goal), start, self.config)

    def _aim(self, goal: FollowGoal, track: TargetTrack, t_end_ns: int) -> Aim:
        predicted = track.predict(t_end_ns)
        assert predicted is not None  # a goal starts only with a frame
        frame = self.frames_of[goal.source]
        R = self.space.rotation_to_base(rotation(frame.ypr), frame.frame)
        assert self.run is not None
        a = self.run.settings.approach
        n = R @ np.array(a)
        return Aim(predicted[0], predicted[1], (float(n[0]), float(n[1]), float(n[2])))

    def _point(self, q: list[float], goal: FollowGoal) -> tuple[float, float, float]:
        """The tracked point where the angles ``q`` put it [m]."""
        p, R = gripper_pose(q, self.config.arm)
        x, y, z = goal.offset
        return (
            p[0] + R[0] * x + R[1] * y + R[2] * z,
            p[1] + R[3] * x + R[4] * y + R[5] * z,
            p[2] + R[6] * x + R[7] * y + R[8] * z,
        )

    def observe(self, js: JointState, last: JointState | None) -> None:
        """Place the bodies the newest frames reported, once per joint state, before any
        command is guarded; while no goal runs, note each tracker's newest frame's age (a
        goal's :meth:`command` does it while it runs), so that a goal's start is judged
        with the tracker's latency known (without it a frame one latency and a period old
        counted as lost, and the goal was refused)."""
        if self.goal is None:
            for track in self.tracks.values():
                track.observe(js.stamp_ns)
        self.bodies.place(self.host, self.space, self.report.bodies)

    def _stop_request(self, goal_id: str) -> GoalAck:
        current = self.goal or self.pending
        if current is None or (goal_id and goal_id != current.goal_id):
            why = f"no follow goal {goal_id!r} runs"
            return _ack(goal_id, Refused(Refusal.UNKNOWN_GOAL, why))
        self.stop(End(ResultStatus.CANCELLED, EndCause.CANCEL_REQUEST, "stopped on request"))
        return _ack(goal_id)

    def _fault(self, cause: EndCause, reason: str) -> None:
        """A fault found by a frame: the goal ends now (zeros replace this cycle's command)."""
        self._end(End(ResultStatus.ABORTED, cause, reason))

    def _end(self, end: End) -> None:
        goal = self.goal
        if goal is None:
            return
        js = self.host.last_js
        duration = 0 if js is None else js.stamp_ns - self.started_ns
        self._finish(goal, end, duration)
        self.report.end_with(goal, end)
        self.goal, self.run = None, None

    def _finish(self, goal: FollowGoal, end: End, duration_ns: int) -> None:
        outcome = GoalOutcome(
            goal.goal_id,
            GoalKind.FOLLOW,
            end.status,
            end.cause,
            end.reason,
            final_error=self.report.distance if self.goal is goal else 0.0,
            duration=max(duration_ns, 0) / 1e9,
            clearance=self.host.clearance(goal.goal_id),
        )
        self.host.finish(outcome)
