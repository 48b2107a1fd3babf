"""The bridge's wiring on the bus side: Zenoh inputs -> :class:`BridgeCore` methods.

The CAN side (frames, ticks, the shutdown) is the shell's own loop; this map drives the
Zenoh side of the live shell (:mod:`.shell`) and of the lock-step harness
(``manus_stack.lockstep``): velocity commands, e-stops, the supervisor's heartbeat (a
fold's deadman) and ``bridge/command``.
"""

from __future__ import annotations

from manus.wiring import Answer, Input, Wiring
from schemas import endpoints as ep
from services.can_bridge.core import BridgeCore, Outputs

WIRING: Wiring[BridgeCore, Outputs] = Wiring(
    ep.Service.CAN_BRIDGE,
    lambda out: out.messages,
    inputs=(
        Input(ep.JOINT_VELOCITY, lambda core, cmd, t: core.on_command(cmd, t)),
        Input(ep.ESTOP, lambda core, msg, t: core.on_estop(msg, t)),
        Input(ep.HEARTBEAT, lambda core, hb, t: core.on_heartbeat(hb, t)),
    ),
    answers=(Answer(ep.BRIDGE_COMMAND, lambda core, req, t: core.on_arm_command(req, t)),),
)
"""The bridge's wiring map (bus side)."""
