"""What the follow source shows of its goal: the ``FollowState`` of each cycle.

:class:`FollowReport` keeps what one cycle of the follow law found (the predicted target,
the standoff point, the speed cap, what held the motion back, the collision guard's
verdict) and the end of the goal, and builds the state from it and the joint state the
command answers (the tracked point there, measured).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from manus.kinematics import Vec3
from schemas.follow import FollowGoal, FollowPhase, FollowState
from schemas.jog import JogLimit
from schemas.state import JointState
from services.controller.command_source import End
from services.controller.follow_law import Aim, FollowStep
from services.controller.jog_limits import Slowdown
from services.controller.target_track import TargetTrack


def _limit(lim: Slowdown) -> JogLimit:
    return JogLimit(
        kind=lim.kind,
        object=lim.object,
        scale=min(1.0, max(0.0, lim.scale)),
        body=lim.body,
        distance=max(0.0, lim.distance) if math.isfinite(lim.distance) else 0.0,
        angle=lim.angle,
    )


def _xyz(v: Vec3 | None) -> list[float]:
    return [] if v is None else [float(v[0]), float(v[1]), float(v[2])]


@dataclass
class FollowReport:
    """The follow goal as the state shows it (see the module docstring).

    Attributes:
        step: this cycle's step of the follow law (None: none yet).
        aim: this cycle's prediction.
        age_ns: the newest frame's age at this joint state [ns].
        guard: what the collision guard did to this cycle's command (None: nothing).
        distance: from the tracked point to the standoff point at the last state [m].
        frames: frames of the followed tracker taken while the goal ran.
        ended_goal: the goal that ended and whose last state is still to be shown.
        end: how it ended.
        bodies: where each person body the trackers moved is, base frame (4x4).
    """

    step: FollowStep | None = None
    aim: Aim | None = None
    age_ns: int = 0
    guard: Slowdown | None = None
    distance: float = 0.0
    frames: int = 0
    ended_goal: FollowGoal | None = None
    end: End | None = None
    bodies: dict[str, np.ndarray] = field(default_factory=dict)
    _seq: int = 0

    def begin(self, goal: FollowGoal) -> None:
        """A goal starts: nothing of the last one is shown any more."""
        self.step, self.aim, self.guard = None, None, None
        self.frames, self.distance = 0, 0.0
        self.ended_goal, self.end = None, None
        del goal

    def cycle(self, step: FollowStep, aim: Aim, age_ns: int) -> None:
        """This cycle's step of the follow law and its prediction."""
        self.step, self.aim, self.age_ns = step, aim, age_ns

    def end_with(self, goal: FollowGoal, end: End) -> None:
        """The goal ended: its last state is shown at the next joint state."""
        self.ended_goal, self.end = goal, end

    def state(
        self,
        js: JointState,
        goal: FollowGoal,
        point: Vec3,
        track: TargetTrack | None,
        hold_m: float,
    ) -> FollowState:
        """The state for the joint state ``js`` (``point``: the tracked point there;
        ``hold_m``: within this of the standoff point it holds)."""
        step, aim = self.step, self.aim
        ended = self.ended_goal is goal and self.end is not None
        limits = [] if step is None else [_limit(lim) for lim in step.limits]
        if self.guard is not None:
            limits.append(_limit(self.guard))
            self.guard = None
        if step is not None:
            self.distance = math.dist(step.aim, point)
        newest = None if track is None else track.newest
        body = next(iter(self.bodies), "")
        pose = self.bodies.get(body)
        if ended:
            assert self.end is not None
            phase, cause, reason = FollowPhase.ENDED, str(self.end.cause), self.end.reason
            self.ended_goal = None
        elif step is not None and self.distance <= hold_m:
            phase, cause, reason = FollowPhase.HOLDING, "", "holding at the standoff point"
        else:
            phase, cause, reason = FollowPhase.APPROACHING, "", "approaching the standoff point"
        if not ended and limits:
            tight = min(limits, key=lambda lim: lim.scale)
            reason += f"; slowed to {tight.scale:.2f} by {tight.kind} ({tight.object})"
        out = FollowState(
            stamp_ns=js.stamp_ns,
            seq=self._seq,
            goal_id=goal.goal_id,
            source=goal.source,
            state=phase,
            cause=cause,
            reason=reason,
            target_xyz=_xyz(newest.xyz if newest is not None else None),
            target_stamp_ns=newest.stamp_ns if newest is not None else 0,
            predicted_xyz=_xyz(aim.target if aim is not None else None),
            aim_xyz=_xyz(step.aim if step is not None else None),
            point_xyz=_xyz(point),
            distance=self.distance,
            speed_cap=step.speed_cap if step is not None else 0.0,
            latency=self.age_ns / 1e9,
            body=body,
            body_xyz=[] if pose is None else [float(v) for v in pose[:3, 3]],
            limits=limits,
            frames=self.frames,
        )
        self._seq += 1
        return out
