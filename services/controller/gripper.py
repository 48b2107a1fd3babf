"""The gripper loop: drive the opening to a target with gripper increments.

Each cycle the opening expected when the command takes effect is predicted from the
increment in flight (the same delay as the joints), and the increment that closes the
rest of the gap over one cycle is commanded, scaled by ``gripper_gain`` x cycle and
rounded to the arm's 0.1 mm per 20 ms steps (limit 15). The goal succeeds once the
measured opening is within its tolerance and nothing moves any more; it aborts after its
timeout.
"""

from __future__ import annotations

from dataclasses import dataclass

from manus.quantize import GRIPPER_COUNT_M_S, gripper_counts
from schemas.control import GripperGoal
from services.controller.config import ControllerConfig
from services.controller.estimator import DriveEstimator, deadbeat_speed


@dataclass
class GripperRun:
    """A running gripper goal.

    Attributes:
        goal: the goal.
        start_ns: snapshot time of its first cycle [ns] (None before it starts).
        cancelled: a cancel came in; the next cycle commands zero and ends it.
        heartbeat_since_ns: stamp of the first joint state its deadman judged [ns] (the
            deadman's reference until a newer heartbeat; None before).
    """

    goal: GripperGoal
    start_ns: int | None = None
    cancelled: bool = False
    heartbeat_since_ns: int | None = None


def gripper_command(
    config: ControllerConfig, est: DriveEstimator, target_m: float, cancelled: bool
) -> int:
    """The gripper increment [counts] for this cycle.

    Args:
        config: timing and gain.
        est: the gripper's estimator, updated with this cycle's reading.
        target_m: wanted opening [m].
        cancelled: stop: zero.
    """
    if cancelled or est.x is None:
        return 0
    tau = config.drive_tau_ms / 1000.0
    delay = config.command_delay_ms / 1000.0
    (x1,), v1 = est.predict(delay)
    aim = x1 + (target_m - x1) * min(1.0, config.gripper_gain * config.cycle_s)
    (u,) = deadbeat_speed([x1], v1, [aim], config.cycle_s, tau)
    return gripper_counts(u)


def gripper_speed(counts: int) -> float:
    """Opening speed [m/s] of a gripper increment."""
    return counts * GRIPPER_COUNT_M_S
