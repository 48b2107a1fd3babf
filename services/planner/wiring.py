"""The planner's wiring: joint states (the default start), ``planner/plan`` and
``planner/scene``.

Drives the live shell (:mod:`.shell`, which plans outside the node lock), the lock-step
harness (``manus_stack.task_lockstep``) and the regression check
(``manus_stack.regression``).
"""

from __future__ import annotations

from manus.wiring import Answer, Input, Publications, Wiring, messages
from schemas import endpoints as ep
from schemas.collision import SceneReply, SceneUpdate
from schemas.state import JointState
from services.planner.core import PlannerCore


def _on_joint_state(core: PlannerCore, js: JointState, t_ns: int) -> Publications:
    """The default start; now and then the scene in use (late joiners, recordings)."""
    state = core.on_joint_state(js)
    return [] if state is None else [(ep.SCENE_STATE, state)]


def _on_scene(core: PlannerCore, update: SceneUpdate, t_ns: int) -> tuple[SceneReply, Publications]:
    """Replace the scene; an accepted one is published for the guard and the fold check."""
    reply = core.update_scene(update)
    state = core.scene_state
    return reply, [(ep.SCENE_STATE, state)] if reply.accepted and state is not None else []


WIRING: Wiring[PlannerCore, Publications] = Wiring(
    ep.Service.PLANNER,
    messages,
    inputs=(Input(ep.JOINTS, _on_joint_state),),
    answers=(
        Answer(ep.PLAN, lambda core, req, t: (core.plan(req), []), locked=False),
        Answer(ep.SCENE, _on_scene, locked=False),
    ),
)
"""The planner's wiring map (its replies, and the scene in use on ``planner/scene_state``)."""
