"""A follow goal as the viewer draws it (``P/viz/follow``): the target the tracker saw, the
target predicted to when the command acts, the standoff point and the approach axis to
it, the arm's tracked point, and the person's body where the guard has it; all in the base
frame. A goal that ended is deleted."""

from __future__ import annotations

from foxglove.messages import SceneUpdate

from schemas.follow import FollowPhase, FollowState
from services.viewer import scene
from services.viewer.model import ROOT_FRAME

TARGET_RGBA = (1.00, 0.20, 0.20, 1.0)
PREDICTED_RGBA = (1.00, 0.65, 0.10, 0.9)
STANDOFF_RGBA = (0.20, 0.90, 0.40, 1.0)
POINT_RGBA = (0.90, 0.90, 1.00, 1.0)
BODY_RGBA = (1.00, 0.30, 0.30, 0.25)
ENTITIES = ("follow_target", "follow_predicted", "follow_standoff", "follow_point", "follow_body")
"""The entities of ``P/viz/follow``."""


def follow_update(state: FollowState, t_ns: int) -> SceneUpdate:
    """The scene update for one ``FollowState`` (stamped with its joint state's stamp)."""
    if state.state == FollowPhase.ENDED:
        return scene.delete_entities(ENTITIES, t_ns)
    stamp = state.stamp_ns
    ents = []
    if state.target_xyz:
        label = f"{state.source}: {state.state}, {state.distance * 1e3:.0f} mm"
        ents.append(
            scene.path_entity(
                "follow_target",
                ROOT_FRAME,
                stamp,
                [],
                TARGET_RGBA,
                markers=[state.target_xyz],
                marker_size=0.014,
                labels=[label],
            )
        )
    if state.predicted_xyz:
        ents.append(
            scene.path_entity(
                "follow_predicted",
                ROOT_FRAME,
                stamp,
                [],
                PREDICTED_RGBA,
                markers=[state.predicted_xyz],
                marker_size=0.010,
            )
        )
    if state.aim_xyz and state.predicted_xyz:
        ents.append(
            scene.path_entity(
                "follow_standoff",
                ROOT_FRAME,
                stamp,
                [state.predicted_xyz, state.aim_xyz],
                STANDOFF_RGBA,
                markers=[state.aim_xyz],
                marker_size=0.012,
                thickness=0.002,
            )
        )
    if state.point_xyz:
        ents.append(
            scene.path_entity(
                "follow_point",
                ROOT_FRAME,
                stamp,
                [],
                POINT_RGBA,
                markers=[state.point_xyz],
                marker_size=0.008,
            )
        )
    if state.body_xyz:
        ents.append(
            scene.path_entity(
                "follow_body",
                ROOT_FRAME,
                stamp,
                [],
                BODY_RGBA,
                markers=[state.body_xyz],
                marker_size=0.04,
                labels=[state.body],
            )
        )
    return scene.scene_update(ents, stamp)
