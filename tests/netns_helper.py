"""Small processes the two-host test runs inside its network namespaces.

    python -m tests.netns_helper router          # a Zenoh router from $MANUS_ZENOH_CONFIG
    python -m tests.netns_helper probe OUT.txt   # every can/tx frame: "stamp_ns id zero"

Both run until SIGINT/SIGTERM. The router is the Python equivalent of the ``zenohd``
that compose.yaml runs, configured by the same file of ``deploy/zenoh/``.
"""

from __future__ import annotations

import sys

from manus.node import Node
from manus.process import wait_for_signal
from manus.protocol import FrameId, decode_move
from manus.session import open_session, settings_from_env
from schemas import endpoints as ep
from schemas.state import CanFrame


def _router() -> int:
    stop = wait_for_signal()
    session = open_session(settings_from_env())
    try:
        print("router: up", file=sys.stderr, flush=True)
        stop.wait()
    finally:
        session.close()
    return 0


def _probe(out: str) -> int:
    stop = wait_for_signal()
    with (
        open(out, "w", encoding="utf-8") as stream,
        Node("netns-probe", settings_from_env(), liveliness=False) as node,
    ):

        def on_tx(frame: CanFrame, rx_ns: int) -> None:
            zero = frame.id == FrameId.JOINT and decode_move(frame.id, frame.data).is_zero
            stream.write(f"{frame.stamp_ns} {frame.id} {int(zero)}\n")
            stream.flush()

        node.subscribe(node.keys(ep.CAN_TX), CanFrame, on_tx)
        print("probe: up", file=sys.stderr, flush=True)
        stop.wait()
    return 0


def main(argv: list[str]) -> int:
    """``router`` or ``probe OUT``."""
    if argv[:1] == ["router"]:
        return _router()
    if argv[:1] == ["probe"] and len(argv) == 2:
        return _probe(argv[1])
    print("usage: python -m tests.netns_helper router | probe OUT.txt", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
