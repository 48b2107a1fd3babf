"""The keys the panel uses: all it may do on the bus (its identity's rights in the
deployed access control, :mod:`manus_stack.policy`), besides reading the liveliness tokens.

The panel acts for the supervisor on these keys only: it publishes the jog and the e-stop,
submits and controls tasks, reads a task's state and sets the jog's speed level; it cannot
replace the planner's scene, trigger the flight recorder or control a replay.
"""

from __future__ import annotations

from schemas import endpoints as ep

PANEL_KEYS: tuple[ep.Endpoint, ...] = (
    ep.EVENTS,
    ep.JOG_STATE,
    ep.ESTOP,
    ep.JOG,
    ep.SUBMIT,
    ep.TASK_CONTROL,
    ep.TASK_STATUS,
    ep.JOG_LEVEL,
)
"""Every key the panel subscribes to, publishes on or queries."""
