"""The sequencer's wiring: what it follows on the bus, the queries it answers.

Drives the live shell (:mod:`.shell`) and the lock-step harness
(``manus_stack.task_lockstep``). The core's outputs are :data:`~.actions.Action` values:
:class:`~.actions.Publish` ones are its publications (task events, the deadman heartbeat);
:class:`~.actions.Query` ones are requests to other services, carried by the shell's worker
(live) or answered by the owning core (lock-step); :class:`~.actions.Reply` ones (a
``Publish`` subclass) answer a submission, to its submitter only, not published.
Liveliness changes come from the node's token watch.
"""

from __future__ import annotations

from collections.abc import Iterable

from manus.wiring import Answer, Input, Wiring
from schemas import endpoints as ep
from schemas.base import Message
from services.sequencer.actions import Action, Publish, Reply
from services.sequencer.core import SequencerCore


def publications(actions: Iterable[Action]) -> list[tuple[str, Message]]:
    """The :class:`Publish` actions among ``actions`` (a :class:`Reply` is not one: it
    goes to one submitter), as (key suffix, message)."""
    return [
        (a.suffix, a.message)
        for a in actions
        if isinstance(a, Publish) and not isinstance(a, Reply)
    ]


WIRING: Wiring[SequencerCore, list[Action]] = Wiring(
    ep.Service.SEQUENCER,
    publications,
    inputs=(
        Input(ep.JOINTS, lambda core, js, t: core.on_joint_state(js, t)),
        Input(ep.BRIDGE_STATE, lambda core, bs, t: core.on_bridge_state(bs, t)),
        Input(ep.FEEDBACK, lambda core, fb, t: core.on_feedback(fb, t)),
        Input(ep.RESULT, lambda core, res, t: core.on_result(res, t)),
        Input(ep.FOLLOW_STATE, lambda core, msg, t: core.on_follow_state(msg, t)),
        Input(ep.ESTOP, lambda core, msg, t: core.on_estop(msg, t)),
        Input(ep.SCENE_STATE, lambda core, scene, t: core.on_scene(scene)),
        Input(ep.OBJECTS, lambda core, update, t: core.on_objects(update, t)),
        Input(ep.JOG_STATE, lambda core, msg, t: core.on_jog_state(msg, t)),
        Input(ep.GUARDIAN_REPORT, lambda core, msg, t: core.on_guardian_report(msg, t)),
    ),
    answers=(
        Answer(ep.TASK_CONTROL, lambda core, req, t: core.control(req, t)),
        Answer(ep.TASK_STATUS, lambda core, req, t: (core.status(), [])),
        Answer(ep.HISTORY, lambda core, req, t: (core.history(req.limit), [])),
    ),
)
"""The sequencer's wiring map. ``sequencer/submit`` is not among its answers: the core
answers a submission later (:meth:`SequencerCore.submit` -> plan queries -> a
:class:`~.actions.Reply`); the shell's handler waits for that reply
(:meth:`.shell.SequencerShell._on_submit`) and the lock-step harness collects it."""
