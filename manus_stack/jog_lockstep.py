"""A lock-step arm driven live: a jog stream into the controller, the simulator's truth out.

:class:`JogArm` is a :class:`~manus_stack.controlled.ControlledArm` (simulator, bridge and
controller cores on the simulated clock) with a sender that publishes
:class:`~schemas.jog.JogCommand` on ``jog`` at its own rate, as a supervisor or a
joystick would, and a probe that samples the simulator's true state every
``sample_s``: gripper pose and the motors' true speeds. Tests and ``manus bench jog``
judge the jog on these samples, never on what the stack reports.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from manus.orientation import ypr_to_matrix
from manus_stack.controlled import ControlledArm
from schemas import endpoints as ep
from schemas.jog import JogCommand, JogState
from services.controller.config import ControllerConfig
from services.simulator.config import SimConfig

REST_DEG_S = 0.5
"""A motor slower than this counts as at rest [deg/s] (the drives' lag never reaches 0)."""


class TruthSample(NamedTuple):
    """The simulator's true state at one instant.

    Attributes:
        t_ns: simulated time [ns].
        xyz: true gripper position [m], shape (3,).
        R: true gripper orientation, shape (3, 3).
        speed: fastest true motor speed [deg/s].
        gripper_speed: true gripper speed [mm/s].
        q: true DH joint angles [rad], shape (6,).
    """

    t_ns: int
    xyz: np.ndarray
    R: np.ndarray
    speed: float
    gripper_speed: float
    q: np.ndarray

    @property
    def at_rest(self) -> bool:
        """Every motor and the gripper slower than :data:`REST_DEG_S` (mm/s for it)."""
        return self.speed < REST_DEG_S and abs(self.gripper_speed) < REST_DEG_S


class JogArm(ControlledArm):
    """Lock-step arm with a jog sender and a truth probe (see the module docstring).

    Args:
        sim: simulator settings (default: the unfolded start).
        config: controller settings.
        sample_s: truth sampling step [s].
    """

    def __init__(
        self,
        sim: SimConfig | None = None,
        config: ControllerConfig | None = None,
        sample_s: float = 0.005,
    ) -> None:
        super().__init__(sim or SimConfig(start_pose="unfolded"), config)
        self.sample_ns = round(sample_s * 1e9)
        self.samples: list[TruthSample] = []
        self.sent: list[tuple[int, JogCommand]] = []
        """Every command published, with its publication time [ns]."""
        self._seq = 0

    @staticmethod
    def make_command(seq: int, stamp_ns: int, **fields: Any) -> JogCommand:
        """A command (defaults: an SI twist in the base frame, all zero: a stop)."""
        base: dict[str, Any] = {"stamp_ns": stamp_ns, "seq": seq, "source": "jogarm"}
        base |= {"kind": "twist", "units": "si"}
        return JogCommand(**(base | fields))

    def command(self, **fields: Any) -> JogCommand:
        """A command stamped now (see :meth:`make_command`)."""
        self._seq += 1
        return self.make_command(self._seq, self.ls.t_ns, **fields)

    def send(self, **fields: Any) -> JogCommand:
        """Publish one command now."""
        cmd = self.command(**fields)
        self.ls.publish(ep.JOG, cmd)
        self.sent.append((self.ls.t_ns, cmd))
        return cmd

    def run(self, seconds: float) -> None:
        """Run ``seconds`` of simulated time, sampling the truth."""
        end = self.ls.t_ns + round(seconds * 1e9)
        while self.ls.t_ns < end:
            self.ls.run_until(min(end, self.ls.t_ns + self.sample_ns))
            self.samples.append(self.sample())

    def stream(
        self,
        seconds: float,
        rate_hz: float = 20.0,
        until: Callable[[TruthSample], bool] | None = None,
        **fields: Any,
    ) -> None:
        """Publish the same command every 1 / ``rate_hz`` for ``seconds`` (or until
        ``until`` holds for a truth sample), sampling the truth."""
        period = round(1e9 / rate_hz)
        end = self.ls.t_ns + round(seconds * 1e9)
        while self.ls.t_ns < end:
            if until is not None and self.samples and until(self.samples[-1]):
                return
            self.send(**fields)
            self.run(min(period, end - self.ls.t_ns) / 1e9)

    def sample(self) -> TruthSample:
        """The truth now."""
        t = self.ls.t_ns
        truth = self.ls.sim.truth(t)
        state = self.ls.sim.state_at(t)
        return TruthSample(
            t,
            np.asarray(truth.xyz, dtype=float),
            ypr_to_matrix(*truth.ypr),
            float(np.max(np.abs(state.speed_deg_s))),
            float(state.gripper_speed_mm_s),
            np.asarray(truth.q_true, dtype=float),
        )

    def rest_from(self, t_ns: int) -> int | None:
        """The first sample time from ``t_ns`` on after which the arm stays at rest (None:
        it never comes to rest in the samples)."""
        rest: int | None = None
        for s in self.samples:
            if s.t_ns < t_ns:
                continue
            if not s.at_rest:
                rest = None
            elif rest is None:
                rest = s.t_ns
        return rest

    def first_motion_from(self, t_ns: int) -> int | None:
        """The first sample time from ``t_ns`` on at which the arm moves (None: never)."""
        return next((s.t_ns for s in self.samples if s.t_ns >= t_ns and not s.at_rest), None)

    def states(self) -> list[JogState]:
        """Every JogState the controller published."""
        return [m for m in self.ls.published(ep.JOG_STATE) if isinstance(m, JogState)]


def line_drift(samples: list[TruthSample], direction: np.ndarray) -> tuple[float, float, float]:
    """Largest distance [m] of the samples from the line through the first along
    ``direction``, the distance travelled along it [m], and the largest orientation
    change [deg] from the first sample."""
    d = direction / np.linalg.norm(direction)
    p0, R0 = samples[0].xyz, samples[0].R
    off = [s.xyz - p0 for s in samples]
    drift = max(float(np.linalg.norm(v - (v @ d) * d)) for v in off)
    along = max(float(v @ d) for v in off)
    turned = max(_angle_deg(R0, s.R) for s in samples)
    return drift, along, turned


def _angle_deg(A: np.ndarray, B: np.ndarray) -> float:
    cos = (float(np.trace(A.T @ B)) - 1.0) / 2.0
    return math.degrees(math.acos(max(-1.0, min(1.0, cos))))
