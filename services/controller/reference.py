"""The reference a goal follows: a joint trajectory, plus the blend of a splice.

When a trajectory replaces the running one while the arm moves (``replace=True``), the
difference between the old reference and the new trajectory at the splice time (in
position, velocity and acceleration) is added to the new trajectory and faded out by a
quintic over the blend time: the reference stays continuous up to the acceleration and
ends exactly on the new trajectory. Times here are trajectory times tau [s] (the
controller maps them to the arm's clock through its time base and speed scale).
"""

from __future__ import annotations

import numpy as np

from manus.config import ArmConfig
from manus.kinematics import fk_position
from manus.trajectory import JointTrajectory, Sample, quintic_coefficients
from schemas.planning import Trajectory


class Reference:
    """A trajectory with an optional fading offset (see the module docstring).

    Args:
        msg: the trajectory message (validated here).
        blend: quintic coefficients of the offset, shape (6, n), or None.
        blend_s: length of the blend [s].
        arm: the arm model (forward kinematics of knots without ``via_xyz``).

    Raises:
        manus.trajectory.TrajectoryError: the trajectory is inconsistent.
    """

    def __init__(
        self,
        msg: Trajectory,
        blend: np.ndarray | None = None,
        blend_s: float = 0.0,
        *,
        arm: ArmConfig,
        blend_from: float = 0.0,
    ) -> None:
        self.arm = arm
        self.traj = JointTrajectory(msg)
        self.blend = blend
        self.blend_s = blend_s if blend is not None else 0.0
        self.blend_from = blend_from if blend is not None else 0.0
        """This trajectory's time at the splice, where the blend starts [s]."""
        self.via_xyz = (
            np.asarray(msg.via_xyz, dtype=float)
            if len(msg.via_xyz) == len(msg.times)
            else np.array([fk_position(q, arm) for q in self.traj.q])
        )

    @property
    def times(self) -> np.ndarray:
        """Knot times [s], shape (k,)."""
        return self.traj.times

    @property
    def duration(self) -> float:
        """Time after which the reference rests on the last knot [s]."""
        return max(self.traj.duration, self.blend_from + self.blend_s)

    @property
    def end(self) -> np.ndarray:
        """Final joint angles [rad], shape (6,)."""
        return self.traj.end

    def sample(self, tau: float) -> Sample:
        """Reference at trajectory time ``tau`` [s] (blend included)."""
        s = self.traj.sample(tau)
        u = tau - self.blend_from  # time since the splice
        if self.blend is None or u >= self.blend_s:
            return s
        if tau < 0.0:
            # Before this trajectory's start (just before the splice, the cycle that decided
            # it; or a continuation spliced before its time 0): its first-order extension,
            # so that the blend sum continues the old reference.
            s0 = self.traj.sample(0.0)
            s = Sample(s0.q + s0.qd * tau, s0.qd, s0.qdd, -1)
        c = self.blend
        q = c[0] + u * (c[1] + u * (c[2] + u * (c[3] + u * (c[4] + u * c[5]))))
        qd = c[1] + u * (2 * c[2] + u * (3 * c[3] + u * (4 * c[4] + u * 5 * c[5])))
        qdd = 2 * c[2] + u * (6 * c[3] + u * (12 * c[4] + u * 20 * c[5]))
        return Sample(s.q + q, s.qd + qd, s.qdd + qdd, s.segment)

    def position(self, tau: float) -> list[float]:
        """Positions at trajectory time ``tau`` [s] as plain floats (``sample(tau).q``;
        :meth:`manus.trajectory.JointTrajectory.position` outside a splice's blend)."""
        if self.blend is None or tau - self.blend_from >= self.blend_s:
            return self.traj.position(tau)
        out: list[float] = self.sample(tau).q.tolist()
        return out

    def spliced(self, msg: Trajectory, tau: float, blend_s: float, at: float = 0.0) -> Reference:
        """The reference that leaves this one at ``tau`` [s] for ``msg`` (its time ``at``
        there: 0, or where a continuation planned for a given splice time has come to).

        Args:
            msg: the replacing trajectory.
            tau: this reference's time at the splice [s].
            blend_s: fade time of the difference [s], > 0.
            at: the replacing trajectory's time at the splice [s].
        """
        new = Reference(msg, arm=self.arm)
        old, first = self.sample(tau), new.sample(at)
        zero = np.zeros(new.traj.n_joints)
        c = quintic_coefficients(
            old.q - first.q, old.qd - first.qd, old.qdd - first.qdd, zero, zero, zero, blend_s
        )
        return Reference(msg, c, blend_s, arm=self.arm, blend_from=at)


def rest_to_rest(q0: np.ndarray, q1: np.ndarray, duration_s: float, arm: ArmConfig) -> Trajectory:
    """A two-knot quintic trajectory from ``q0`` to ``q1`` [rad], at rest at both ends.

    Used for the thesis mode's final approach (it re-plans locally, in joint space).
    """
    zero = [0.0] * len(q0)
    return Trajectory(
        times=[0.0, float(duration_s)],
        positions=[[float(v) for v in q0], [float(v) for v in q1]],
        velocities=[zero, zero],
        accelerations=[zero, zero],
        via_xyz=[[float(v) for v in fk_position(q, arm)] for q in (q0, q1)],
    )
