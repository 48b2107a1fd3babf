"""The planner shell on a loopback router: plans on request, survives malformed ones."""

from __future__ import annotations

import math
from pathlib import Path as FilePath

import pytest

from manus.config import UNFOLDED_Q_DEG
from manus.node import Node, QueryError
from manus.session import ZenohSettings
from manus.viapoints import load_path
from schemas import endpoints as ep
from schemas.planning import Path, PlanReply, PlanRequest, ViaPointPath
from schemas.state import JointState
from services.planner.core import PlannerCore
from services.planner.shell import PlannerShell
from tests.conftest import eventually

ROOT = FilePath(__file__).resolve().parent.parent
UNFOLDED = [math.radians(q) for q in UNFOLDED_Q_DEG]


def test_planner_shell_answers_queries(zenoh_settings: ZenohSettings) -> None:
    square = load_path(ROOT / "paths" / "thesis_square.txt")
    request = PlanRequest(ViaPointPath(path=square), start=UNFOLDED)
    with (
        PlannerShell(zenoh_settings) as shell,
        Node("test_client", zenoh_settings, liveliness=False) as client,
    ):
        key = client.keys(ep.PLAN)
        assert key == "test/planner/plan"

        def answers() -> bool:
            try:
                client.query(key, request, PlanReply, timeout=1.0)
            except QueryError:
                return False
            return True

        eventually(answers)
        assert "planner" in client.alive_services()

        reply = client.query(key, request, PlanReply)
        assert reply.ok and reply.compute_ms > 0.0
        assert reply.trajectory == PlannerCore().plan(request).trajectory

        # No start in the request and no joint state yet: a structured refusal.
        no_start = PlanRequest(ViaPointPath(path=square))
        refused = client.query(key, no_start, PlanReply)
        assert refused.error is not None and refused.error.reason == "no_state"

        # The newest valid joint state becomes the default start.
        other = [0.2, *UNFOLDED[1:]]
        publisher = client.publisher(client.keys(ep.JOINTS))
        state = JointState(stamp_ns=1, seq=1, position=other, gripper=0.0, valid=True,
                           mode="joint", encoder=[0] * 7, applied_velocity=[0.0] * 6,
                           applied_gripper_velocity=0.0,
                           applied_kind="none", applied_seq=-1)  # fmt: skip

        def started_from_state() -> bool:
            publisher.put(state)
            got = client.query(key, no_start, PlanReply)
            return got.ok and got.start == pytest.approx(other)

        eventually(started_from_state)

        # A payload that is not a PlanRequest: an error reply naming the problem.
        first = next(iter(client.session.get(key, payload=b"\xc1 not msgpack", timeout=5.0)))
        assert first.ok is None
        err = first.err
        assert err is not None
        assert "PlanRequest/2: payload is not MessagePack" in err.payload.to_bytes().decode()
        assert shell.node.bad_payload_count == 1

        # A well-formed request with a malformed path: a PlanError naming the via point.
        late = square.via_points[2]
        broken = Path(via_points=[square.via_points[0], late, late], source="sent.txt")
        reply = client.query(key, PlanRequest(ViaPointPath(path=broken), start=UNFOLDED), PlanReply)
        assert not reply.ok and reply.error is not None
        assert (reply.error.reason, reply.error.via_point, reply.error.line) == ("parse", 2, 5)
        assert "sent.txt:5: via point 2: column time" in reply.error.message

        # ... and the service is still there.
        assert client.query(key, request, PlanReply).ok
        assert (shell.plans, shell.refusals) >= (5, 2)
