"""Settings of the pick, place and give steps (frozen, validated at construction)."""

from __future__ import annotations

from dataclasses import dataclass

from manus.errors import ConfigError


@dataclass(frozen=True)
class PickConfig:
    """How the sequencer picks, places and gives objects (docs/pick.md).

    Attributes:
        grasps: the grasps file ('': the shipped ``manus/data/grasps.yaml``).
        max_tilt_deg: a held object of a class kept level (a cup: it may hold a drink)
            leans at most this far from upright while carried [deg]; every motion planned
            while it is held is checked along its whole trajectory.
        moved_m: the object moved farther than this from where the approach was planned
            to (perception's newest sighting) during the approach: the approach stops and
            is planned again [m].
        max_replans: at most this many new approaches per pick; one more move stops
            the task, saying so.
        lost_s: no update of the world model for longer than this (on its stamps: the
            newest camera frame's capture time) while an object is approached: perception
            is lost, the task stops [s] (0: the world model's own ``stale_after_s``).
        hidden_s: the object itself not observed for longer than this (the arm hides it
            from the camera on its way) before and while the pre-grasp pose is reached:
            the task stops [s]. A straight approach hides it behind the gripper: it is
            not judged then.
        handover_xyz: where ``give`` brings the object's centre, chair frame [m]: in front
            of the user's chest, 450 mm ahead of the torso, within the reach of a hand.
        handover_yaw_deg: the gripper's yaw there (the direction it points in, chair frame)
            [deg]: 120, back toward the user, the object held out at its tip; other yaws
            are tried (:data:`~services.sequencer.carry_stages.GIVE_TURNS_DEG`) when the
            planner refuses this one.
        drop_m: a placed object is let go this far above its resting place [m]: the
            stack knows where it holds it only as well as perception saw it (3 mm per
            axis), and an object pressed onto a surface stops the arm.
        margin_m: every motion of an object task keeps this much beyond each clearance
            (its plan is refused otherwise: another grasp is tried): near the table the
            plans run close to the clearance, and the controller's tracking error must
            not bring the guard's stop [m].
        min_margin_m: when every candidate is too tight for ``margin_m``, they are tried
            again with this much to spare [m] (the guard may then stop the arm near the
            table, safely; the figures in docs/pick.md).
    """

    grasps: str = ""
    max_tilt_deg: float = 10.0
    moved_m: float = 0.025
    max_replans: int = 2
    lost_s: float = 0.0
    hidden_s: float = 5.0
    handover_xyz: tuple[float, float, float] = (0.50, -0.15, 0.95)
    handover_yaw_deg: float = 120.0
    drop_m: float = 0.010
    margin_m: float = 0.010
    min_margin_m: float = 0.006

    def __post_init__(self) -> None:
        if not 0.0 < self.max_tilt_deg <= 90.0:
            raise ConfigError(f"pick max_tilt_deg = {self.max_tilt_deg!r} is outside (0, 90] deg")
        if not 0.0 < self.moved_m <= 0.5:
            raise ConfigError(f"pick moved_m = {self.moved_m!r} is outside (0, 0.5] m")
        if not 0 <= self.max_replans <= 10:
            raise ConfigError(f"pick max_replans = {self.max_replans!r} is outside 0..10")
        if not 0.0 <= self.lost_s <= 60.0:
            raise ConfigError(f"pick lost_s = {self.lost_s!r} is outside 0..60 s")
        if not 0.1 <= self.hidden_s <= 60.0:
            raise ConfigError(f"pick hidden_s = {self.hidden_s!r} is outside 0.1..60 s")
        if not 0.0 <= self.margin_m <= 0.05:
            raise ConfigError(f"pick margin_m = {self.margin_m!r} is outside 0..0.05 m")
        if not 0.0 <= self.min_margin_m <= self.margin_m:
            raise ConfigError(
                f"pick min_margin_m = {self.min_margin_m!r} is outside 0..margin_m "
                f"({self.margin_m!r}) m"
            )
        if not 0.0 <= self.drop_m <= 0.05:
            raise ConfigError(f"pick drop_m = {self.drop_m!r} is outside 0..0.05 m")
