"""A lock-step arm following the simulator's moving target, judged on the simulator's truth.

:class:`FollowArm` is a :class:`~manus_stack.controlled.ControlledArm` (simulator, bridge
and controller cores on the simulated clock) whose simulator runs a moving target
(:mod:`services.simulator.target`: its tracker publishes on ``target/pose``), with a probe
that samples the simulator's truth every ``sample_s``: where the arm's tracked point
truly is, where the true standoff point of the true target is (the follow law's own
:meth:`~services.controller.follow_law.FollowRun.standoff_point`, on the true head), the
true distance of the arm's bodies to the person, of the tracked point to the person, and
the motors' true speeds. Tests and ``manus bench follow`` judge following on these
samples, never on what the stack reports.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from manus.kinematics import Vec3, gripper_pose
from manus.orientation import ypr_to_matrix
from manus.scene import Scene, scene_from_setting
from manus_stack.controlled import ControlledArm
from schemas import endpoints as ep
from schemas.control import GoalAck, GoalResult
from schemas.follow import FollowGoal, FollowState
from services.controller.config import ControllerConfig
from services.controller.follow_law import Aim, Settings, standoff_point
from services.controller.follow_space import FollowSpace
from services.simulator.config import SimConfig


class FollowSample(NamedTuple):
    """The simulator's truth at one instant, as following is judged.

    Attributes:
        t_ns: simulated time [ns].
        point: the arm's tracked point, base frame [m].
        aim: the true standoff point (None: no goal set yet).
        target: the true target point, base frame [m].
        speed: the fastest true motor speed [deg/s].
        point_speed: the tracked point's true speed [m/s] (0 at the first sample).
        person: the arm's bodies' true distance to the nearest person [m] (None: none).
        pair: ``body/object`` of ``person``.
        rim: the tracked point's true distance to the nearest person [m].
        closing: the arm's own motion since the last sample brought the tracked point
            closer to the person (judged with the person where it is now).
        visible: the tracker sees the target.
    """

    t_ns: int
    point: Vec3
    aim: Vec3 | None
    target: Vec3
    speed: float
    point_speed: float
    person: float | None
    pair: str
    rim: float
    closing: bool
    visible: bool

    @property
    def error(self) -> float:
        """From the tracked point to the true standoff point [m] (nan: no goal)."""
        return math.dist(self.point, self.aim) if self.aim is not None else math.nan


class FollowArm(ControlledArm):
    """Lock-step arm, a moving target and a truth probe (see the module docstring).

    Args:
        sim: simulator settings (its ``target`` enabled).
        config: controller settings.
        sample_s: truth sampling step [s].
    """

    def __init__(
        self,
        sim: SimConfig,
        config: ControllerConfig | None = None,
        sample_s: float = 0.010,
    ) -> None:
        super().__init__(sim, config)
        self.sample_ns = round(sample_s * 1e9)
        self.samples: list[FollowSample] = []
        self.goal: FollowGoal | None = None
        scene = scene_from_setting(sim.scene)
        self._scene: Scene | None = scene
        self._space = FollowSpace(scene, self.core.config.arm)
        self._settings: Settings | None = None

    def follow(self, **fields: Any) -> GoalAck:
        """Submit a follow goal (``goal_id`` and ``source`` default to ``f1`` and the
        simulator's target); the probe measures against its standoff point from now on."""
        base: dict[str, Any] = {"goal_id": "f1", "source": self.ls.sim.config.target.source}
        goal = FollowGoal(**(base | fields))
        ack = self.query(ep.FOLLOW, goal)
        if ack.accepted:
            self.goal = goal
            cfg = self.core.config.follow
            n = math.sqrt(sum(v * v for v in goal.approach))
            a, b, c = (v / n for v in goal.approach)
            x, y, z = goal.offset
            clearance = goal.close_clearance if goal.close else self._space.person_clearance
            standoff = goal.standoff or cfg.standoff_m
            cap = goal.max_speed or cfg.max_speed
            self._settings = Settings(standoff, (a, b, c), (x, y, z), cap, clearance, goal.close)
        return ack

    def stop(self) -> GoalAck:
        """Stop the goal."""
        assert self.goal is not None
        return self.query(ep.FOLLOW, FollowGoal(goal_id=self.goal.goal_id, stop=True))

    def run(self, seconds: float) -> None:
        """Run ``seconds`` of simulated time, sampling the truth."""
        end = self.ls.t_ns + round(seconds * 1e9)
        while self.ls.t_ns < end:
            self.ls.run_until(min(end, self.ls.t_ns + self.sample_ns))
            self.samples.append(self.sample())

    def sample(self) -> FollowSample:
        """The truth now."""
        t = self.ls.t_ns
        sim = self.ls.sim
        truth = sim.truth(t)
        state = sim.state_at(t)
        target = truth.target
        assert target is not None, "the simulator runs no moving target"
        space = self._space
        if target.body and target.body_xyz:
            pose = np.eye(4)
            pose[:3, :3] = ypr_to_matrix(*target.body_ypr)
            pose[:3, 3] = target.body_xyz
            space.move_person(target.body, space.to_base @ pose)
        tx = space.point_to_base(target.xyz, "chair")
        settings = self._settings
        ox, oy, oz = settings.offset if settings is not None else (0.0, 0.0, 0.0)
        p, R = gripper_pose(truth.q_true, self.core.config.arm)
        point = (
            p[0] + R[0] * ox + R[1] * oy + R[2] * oz,
            p[1] + R[3] * ox + R[4] * oy + R[5] * oz,
            p[2] + R[6] * ox + R[7] * oy + R[8] * oz,
        )
        aim = None
        if settings is not None:
            Rt = space.rotation_to_base(ypr_to_matrix(*target.ypr), "chair")
            n = Rt @ np.array(settings.approach)
            normal = (float(n[0]), float(n[1]), float(n[2]))
            aim = standoff_point(settings, Aim(tx, (0.0, 0.0, 0.0), normal), space)
        last = self.samples[-1] if self.samples else None
        speed = 0.0
        if last is not None and t > last.t_ns and (last.aim is None) == (aim is None):
            speed = math.dist(point, last.point) / ((t - last.t_ns) / 1e9)
        rim, _ = space.person_distance(point)
        closing = False
        if last is not None and last.aim is not None and aim is not None:
            before, _ = space.person_distance(last.point)  # the same person, where it is now
            closing = rim < before
        return FollowSample(
            t,
            point,
            aim,
            tx,
            float(np.max(np.abs(state.speed_deg_s))),
            speed,
            truth.person_clearance,
            truth.person_pair,
            rim,
            closing,
            target.visible,
        )

    def states(self) -> list[FollowState]:
        """Every FollowState the controller published."""
        return [m for m in self.ls.published(ep.FOLLOW_STATE) if isinstance(m, FollowState)]

    def follow_results(self) -> list[GoalResult]:
        """Every result of a follow goal so far."""
        return [r for r in self.results() if r.kind == "follow"]
