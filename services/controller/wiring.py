"""The controller's wiring: bus inputs -> :class:`ControllerCore` methods, its outputs.

The core's own inputs (the bridge's states, the planner's scene, vanished liveliness
tokens) and, for every command source of the registry (:data:`.sources.SOURCES`), the
publications it takes and the queryables it answers (``INPUTS`` and ``ANSWERS`` of its
class). Drives the live shell (:mod:`.shell`), the lock-step harness
(``manus_stack.controlled``) and the regression check (``manus_stack.regression``).
"""

from __future__ import annotations

from typing import Any

from manus.wiring import Answer, Input, Wiring, messages
from schemas import endpoints as ep
from services.controller.command_source import CommandSource, SourceAnswer, SourceInput
from services.controller.core import ControllerCore
from services.controller.outbox import Output
from services.controller.sources import SOURCES


def _input(kind: type[CommandSource], row: SourceInput) -> Input[ControllerCore, Any, Output]:
    handle, bad = row.handle, row.bad
    return Input(
        row.endpoint,
        lambda core, msg, t: core.take(kind, handle, msg),
        bad=None if bad is None else lambda core, error, t: core.take(kind, bad, error),
    )


def _answer(
    kind: type[CommandSource], row: SourceAnswer
) -> Answer[ControllerCore, Any, Any, Output]:
    handle, query = row.handle, row.endpoint.suffix
    return Answer(row.endpoint, lambda core, req, t: core.ask(kind, handle, query, req))


WIRING: Wiring[ControllerCore, Output] = Wiring(
    ep.Service.CONTROLLER,
    messages,
    inputs=(
        Input(ep.JOINTS, lambda core, js, t: core.on_joint_state(js)),
        Input(ep.STATUS, lambda core, st, t: core.on_status(st)),
        Input(ep.BRIDGE_STATE, lambda core, bs, t: core.on_bridge_state(bs)),
        Input(ep.SCENE_STATE, lambda core, scene, t: core.on_scene(scene)),
        Input(ep.OBJECTS, lambda core, update, t: core.on_objects(update)),
        *(_input(kind, row) for kind in SOURCES for row in kind.INPUTS),
    ),
    answers=tuple(_answer(kind, row) for kind in SOURCES for row in kind.ANSWERS),
    token_gone=lambda core, service, t: core.on_token_gone(service),
)
"""The controller's wiring map."""
