"""The planner's wiring: joint states (the default start), ``planner/plan``,
``planner/scene``, perception (the world model, ``planner/objects``) and
``planner/attach`` (an object held by the arm, or released).

Drives the live shell (:mod:`.shell`, which plans outside the node lock), the lock-step
harness (``manus_stack.task_lockstep``) and the regression check
(``manus_stack.regression``).
"""

from __future__ import annotations

import logging

from manus.wiring import Answer, Input, Publications, Wiring, messages
from schemas import endpoints as ep
from schemas.collision import SceneReply, SceneUpdate
from schemas.objects import AttachReply, AttachRequest, Perception
from schemas.state import JointState
from services.planner.core import PlannerCore

log = logging.getLogger("manus.planner")


def _on_joint_state(core: PlannerCore, js: JointState, t_ns: int) -> Publications:
    """The default start; now and then the scene in use (late joiners, recordings)."""
    state = core.on_joint_state(js)
    return [] if state is None else [(ep.SCENE_STATE, state)]


def _on_perception(core: PlannerCore, msg: Perception, t_ns: int) -> Publications:
    """One perception frame into the world model; a refusal is logged (and counted in the
    next update)."""
    refused = core.world.refused
    updates = core.world.observe(msg)
    if core.world.refused != refused:
        log.warning("refused a perception message: %s", core.world.error)
    for update in updates:
        for jump in update.jumps:
            log.warning(
                "object %r jumped %.3f m in %.3f s (at most %.3f m possible), seen by %s",
                jump.id,
                jump.distance,
                jump.interval,
                jump.allowed,
                jump.source,
            )
        if update.base_version != -1:
            for obj in update.objects:
                if obj.stale:
                    log.info("%s", core.world.stale_reason(obj.id))
    return [(ep.OBJECTS, u) for u in updates]


def _on_attach(
    core: PlannerCore, request: AttachRequest, t_ns: int
) -> tuple[AttachReply, Publications]:
    """Attach or detach an object; an accepted change is a diff on ``planner/objects``."""
    reply, updates = core.attach(request)
    if not reply.accepted:
        log.warning("refused to attach or detach: %s", reply.error)
    return reply, [(ep.OBJECTS, u) for u in updates]


def _on_scene(core: PlannerCore, update: SceneUpdate, t_ns: int) -> tuple[SceneReply, Publications]:
    """Replace the scene; an accepted one is published for the guard and the fold check."""
    reply = core.update_scene(update)
    state = core.scene_state
    return reply, [(ep.SCENE_STATE, state)] if reply.accepted and state is not None else []


WIRING: Wiring[PlannerCore, Publications] = Wiring(
    ep.Service.PLANNER,
    messages,
    inputs=(Input(ep.JOINTS, _on_joint_state), Input(ep.PERCEPTION, _on_perception)),
    answers=(
        Answer(ep.PLAN, lambda core, req, t: (core.plan(req), []), locked=False),
        Answer(ep.SCENE, _on_scene, locked=False),
        Answer(ep.ATTACH, _on_attach),
    ),
)
"""The planner's wiring map (its replies, the scene in use on ``planner/scene_state``,
the world model's updates on ``planner/objects``)."""
