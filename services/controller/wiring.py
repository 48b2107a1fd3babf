"""The controller's wiring: bus inputs -> :class:`ControllerCore` methods, its outputs.

Drives the live shell (:mod:`.shell`), the lock-step harness
(``manus_stack.controlled``) and the regression check (``manus_stack.regression``).
"""

from __future__ import annotations

from manus.wiring import Answer, Input, Wiring, messages
from schemas import endpoints as ep
from services.controller.core import ControllerCore
from services.controller.outbox import Output

WIRING: Wiring[ControllerCore, Output] = Wiring(
    ep.Service.CONTROLLER,
    messages,
    inputs=(
        Input(ep.JOINTS, lambda core, js, t: core.on_joint_state(js)),
        Input(ep.STATUS, lambda core, st, t: core.on_status(st)),
        Input(ep.BRIDGE_STATE, lambda core, bs, t: core.on_bridge_state(bs)),
        Input(ep.HEARTBEAT, lambda core, hb, t: core.on_heartbeat(hb)),
        Input(ep.SCENE_STATE, lambda core, scene, t: core.on_scene(scene)),
        Input(ep.OBJECTS, lambda core, update, t: core.on_objects(update)),
        Input(ep.JOG, lambda core, cmd, t: core.on_jog(cmd)),
    ),
    answers=(
        Answer(ep.GOAL, lambda core, goal, t: (core.submit(goal), [])),
        Answer(ep.GRIPPER_GOAL, lambda core, goal, t: (core.submit_gripper(goal), [])),
        Answer(ep.CANCEL, lambda core, req, t: (core.cancel(req), [])),
        Answer(ep.SPEED_SCALE, lambda core, req, t: (core.set_speed_scale(req), [])),
        Answer(ep.JOG_LEVEL, lambda core, req, t: (core.set_jog_level(req), [])),
    ),
)
"""The controller's wiring map."""
