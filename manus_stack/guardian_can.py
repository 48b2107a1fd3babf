"""Which CAN channel ``manus up`` gives the guardian beside a real arm's bridge.

The guardian is a second node on the arm's bus (docs/deployment.md, Faults). Where the
bridge's interface lets several processes open one channel and each receive every frame
(socketcan and the like, :data:`manus.can_sharing.SHARED_INTERFACES`), the guardian opens
the bridge's channel too. A single-reader one (slcan, serial: one serial line, whose
bytes two readers would split) it never shares: it needs a channel of its own, a second
adapter on the same bus (``manus up --guardian-channel``). Without one it is started
anyway, with the bridge's channel as ``--bridge-channel``: it refuses it, stays off and
holds ``disabled/guardian/single_reader_channel`` (``manus status`` shows it).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from manus.can_sharing import DISABLED_SINGLE_READER, second_reader_refusal
from manus.errors import ConfigError


@dataclass(frozen=True)
class GuardianCan:
    """The guardian's CAN arguments and what to say about them.

    Attributes:
        args: ``manus guardian`` arguments (interface, channel, the bridge's).
        note: one line for ``manus up``'s summary.
        disabled: why it stays off (its ``disabled`` token's word; '' : it guards).
    """

    args: list[str] = field(default_factory=list)
    note: str = ""
    disabled: str = ""


def guardian_can(
    bridge_interface: str, bridge_channel: str, interface: str = "", channel: str = ""
) -> GuardianCan:
    """The guardian's channel beside a bridge on ``bridge_channel`` of
    ``bridge_interface``: ``channel`` of ``interface`` if given (default interface: the
    bridge's), else the bridge's channel when it may be shared, else off.

    Raises:
        ConfigError: ``channel`` was given and is the bridge's single-reader channel.
    """
    interface = interface or bridge_interface
    own = channel or bridge_channel
    why = second_reader_refusal(interface, own, bridge_interface, bridge_channel)
    if why and channel:
        raise ConfigError(f"refused: guardian channel {channel}: {why}")
    bridge = ["--bridge-interface", bridge_interface, "--bridge-channel", bridge_channel]
    args = ["--can-interface", interface, "--can-channel", own, *bridge]
    if why:
        return GuardianCan(args, f"guardian: OFF: {why}", DISABLED_SINGLE_READER)
    return GuardianCan(args, f"guardian: {interface} {own}")
