"""The viewer draws a follow goal: the target, the predicted target, the standoff point,
the tracked point and the person's body, from the controller's FollowState; an ended
goal is deleted."""

from __future__ import annotations

from foxglove.messages import SceneUpdate

from schemas import endpoints as ep
from schemas.follow import FollowPhase, FollowState
from services.viewer.core import ViewerCore
from tests.foxglove_client import protobuf_decoder
from tests.test_viewer import _advert


def _state(phase: str = FollowPhase.HOLDING) -> FollowState:
    return FollowState(
        stamp_ns=7_000_000_000, seq=3, goal_id="g", source="mouth", state=phase,
        target_xyz=[-0.27, 0.42, 0.19], predicted_xyz=[-0.27, 0.43, 0.19],
        aim_xyz=[-0.21, 0.43, 0.19], point_xyz=[-0.21, 0.43, 0.19], distance=0.001,
        body="head", body_xyz=[-0.37, 0.42, 0.23],
    )  # fmt: skip


def test_a_follow_state_is_drawn_and_an_ended_goal_deleted() -> None:
    core = ViewerCore()
    key = core.keys(ep.FOLLOW_STATE)
    assert (core.topics.follow, SceneUpdate) in [(t, SceneUpdate) for t, _, _ in core.channels()]
    out = core.on_sample(key, _state().encode(), 7_000_000_000)
    drawn = [m for m in out if m.topic == core.topics.follow]
    assert len(drawn) == 1 and [m.topic for m in out].count(key) == 1  # and its JSON
    update = protobuf_decoder(_advert(drawn[0]))(drawn[0].data)
    ids = {e["id"] for e in update["entities"]}
    assert ids == {"follow_target", "follow_predicted", "follow_standoff", "follow_point",
                   "follow_body"}  # fmt: skip
    target = next(e for e in update["entities"] if e["id"] == "follow_target")
    assert target["spheres"][0]["pose"]["position"]["x"] == -0.27
    assert "mouth: holding, 1 mm" in target["texts"][0]["text"]
    ended = core.on_sample(key, _state(FollowPhase.ENDED).encode(), 7_100_000_000)
    gone = next(m for m in ended if m.topic == core.topics.follow)
    update = protobuf_decoder(_advert(gone))(gone.data)
    assert not update["entities"]
    assert {d["id"] for d in update["deletions"]} >= {"follow_target"}
