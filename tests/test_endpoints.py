"""The endpoint table is the one declaration of the wiring: everything that lists keys is
derived from it, and a key suffix is spelled once in the code base."""

from __future__ import annotations

import ast
import functools
import json
from pathlib import Path
from typing import Any

import pytest
import zenoh

from manus.errors import SchemaError
from manus.wiring import Input, Wiring, WiringError, messages
from manus_stack.lockstep import LockStep
from manus_stack.panel.keys import PANEL_KEYS
from manus_stack.policy import DELEGATES
from schemas import endpoints as ep
from schemas.base import Message
from schemas.commands import EStop
from schemas.control import (
    ControllerFeedback,
    GoalAck,
    GoalResult,
    SpeedScale,
    TrajectoryGoal,
)
from schemas.export import channel_documents, supervisor_document
from schemas.keys import Keys, channel_type, channel_types
from schemas.planning import Trajectory
from schemas.state import BridgeState
from services.controller.wiring import WIRING as CONTROLLER
from services.recorder.replay import service_outputs_table, service_queryables_table

ROOT = Path(__file__).resolve().parents[1]
CODE = ("manus", "schemas", "services", "manus_stack")


@functools.cache
def _trees() -> list[tuple[Path, ast.Module]]:
    """Every module of the code base (tests and examples aside), parsed once."""
    paths = [p for package in CODE for p in sorted((ROOT / package).rglob("*.py"))]
    return [(path, ast.parse(path.read_text(encoding="utf-8"))) for path in paths]


def _string_constants(*, calls_only: bool = False) -> dict[str, list[str]]:
    """Every string constant of the code base (tests and examples aside) -> where; with
    ``calls_only``, those passed to a call (how a key is used: ``keys("estop")``)."""
    found: dict[str, list[str]] = {}
    for path, tree in _trees():
        docstrings = {
            id(node.body[0].value)
            for node in ast.walk(tree)
            if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef)
            and node.body
            and isinstance(node.body[0], ast.Expr)
            and isinstance(node.body[0].value, ast.Constant)
        }
        subscripts = {  # bridge["estop"]: a field name that equals a suffix
            id(node.slice) for node in ast.walk(tree) if isinstance(node, ast.Subscript)
        }
        arguments = {
            id(arg)
            for node in ast.walk(tree)
            if isinstance(node, ast.Call)
            for arg in [*node.args, *(k.value for k in node.keywords)]
        }
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Constant)
                and isinstance(node.value, str)
                and id(node) not in docstrings
                and id(node) not in subscripts
                and (id(node) in arguments or not calls_only)
            ):
                where = f"{path.relative_to(ROOT)}:{node.lineno}"
                found.setdefault(node.value, []).append(where)
    return found


def test_every_key_suffix_is_spelled_once_in_the_code_base() -> None:
    """A suffix with a ``/`` is spelled once (its declaration); a one-word one (``estop``,
    ``heartbeat``, ``alive``, ...) may be a field name or a word elsewhere, but is never
    handed to a call (a key built by hand), its declaration aside."""
    constants = _string_constants()
    in_calls = _string_constants(calls_only=True)
    declared = (
        "schemas/endpoints.py",
        "schemas/object_endpoints.py",
        "schemas/follow_endpoints.py",
        "schemas/liveliness.py",
    )
    for endpoint in ep.TABLE:
        if "/" in endpoint.suffix:
            places = constants.get(endpoint.suffix, [])
            assert len(places) == 1, f"{endpoint.suffix!r} spelled at {places}"
        else:
            places = [p for p in in_calls.get(endpoint.suffix, []) if not p.startswith(declared)]
            assert not places, f"{endpoint.suffix!r} used as a key at {places}"
        assert all(p.startswith(declared) for p in places), places
        for spelled in (f"trace/{endpoint}/request", f"trace/{endpoint}/reply"):
            assert spelled not in constants, (spelled, constants.get(spelled))


def test_the_table_rejects_what_would_make_two_keys_one() -> None:
    with pytest.raises(SchemaError, match="declared twice"):
        ep.TABLE.add(ep.Topic("state/joints", ep.Kind.PUBLICATION, "x", BridgeState))
    with pytest.raises(SchemaError, match="query mirrors"):
        ep.TABLE.add(ep.Topic("trace/x", ep.Kind.PUBLICATION, "x", BridgeState))
    with pytest.raises(SchemaError, match="token root"):
        ep.TABLE.add(ep.Topic("alive/x", ep.Kind.PUBLICATION, "x", BridgeState))
    with pytest.raises(SchemaError, match="reply type iff"):
        ep.Endpoint("x/y", ep.Kind.PUBLICATION, "x", BridgeState, GoalAck)
    with pytest.raises(SchemaError, match="without"):
        ep.Endpoint("x/*", ep.Kind.PUBLICATION, "x", BridgeState)


THROWAWAY_TOPIC = ep.Topic(
    "controller/throwaway", ep.Kind.PUBLICATION, ep.Service.CONTROLLER, ControllerFeedback
)
THROWAWAY_INPUT = ep.Topic("test/poke", ep.Kind.PUBLICATION, ep.ANYONE, SpeedScale)
THROWAWAY_QUERY = ep.Queryable(
    "controller/throwaway_query",
    ep.Kind.QUERYABLE,
    ep.Service.CONTROLLER,
    SpeedScale,
    GoalAck,
    audience=ep.Audience.SUPERVISOR,
    doc="a query that exists only in this test",
)


def test_a_throwaway_endpoint_reaches_everything_derived_from_the_table() -> None:
    """One edit (the table) and keys, channel types, the schema export, the replay's
    stand-in tables and the lock-step harness all see the new endpoints."""
    with ep.TABLE.extended(THROWAWAY_TOPIC, THROWAWAY_INPUT, THROWAWAY_QUERY):
        assert Keys("lab")(THROWAWAY_TOPIC) == "lab/controller/throwaway"
        assert channel_type("controller/throwaway") is ControllerFeedback
        assert channel_type("trace/controller/throwaway_query/request") is SpeedScale
        assert channel_type("trace/controller/throwaway_query/reply") is GoalAck
        index = channel_documents()["index.json"]["channels"]
        assert index["controller/throwaway"] == "manus.ControllerFeedback.1.schema.json"
        assert "controller/throwaway_query#request" in index
        supervisor = supervisor_document()
        assert supervisor["keys"]["controller/throwaway_query"]["request"] == "SpeedScale"
        assert "SpeedScale" in supervisor["$defs"]
        assert "controller/throwaway" in service_outputs_table()["controller"]
        assert "controller/throwaway_query" in service_queryables_table()["controller"]
        # A wiring map made now publishes the new output and takes the new input, and the
        # lock-step harness delivers it to the core, as the live shell would.
        seen: list[tuple[Message, int]] = []

        def poke(core: object, msg: SpeedScale, t_ns: int) -> list[tuple[str, Message]]:
            seen.append((msg, t_ns))
            fb = _feedback()
            return [(THROWAWAY_TOPIC, fb)]

        wiring: Wiring[object, list[tuple[str, Message]]] = Wiring(
            ep.Service.CONTROLLER, messages, inputs=(Input(THROWAWAY_INPUT, poke),)
        )
        assert THROWAWAY_TOPIC in wiring.output_endpoints
        ls = LockStep()
        ls.attach(wiring, object())
        ls.publish(THROWAWAY_INPUT, SpeedScale(scale=0.5))
        ls.run_for(0.01)
        assert seen and seen[0][0] == SpeedScale(scale=0.5)
        assert ls.published("controller/throwaway") == [_feedback()]
    assert channel_type("controller/throwaway") is None  # withdrawn with the block
    assert "controller/throwaway" not in service_outputs_table()["controller"]


def _feedback() -> ControllerFeedback:
    zero = [0.0] * 6
    return ControllerFeedback(
        stamp_ns=0,
        seq=0,
        goal_id="",
        state="idle",
        segment=-1,
        t=0.0,
        reference=zero,
        actual=zero,
        error=zero,
        command=zero,
        reference_xyz=[0.0] * 3,
        actual_xyz=[0.0] * 3,
        position_error=0.0,
    )


def test_a_core_output_the_map_does_not_know_is_an_error_in_every_shell() -> None:
    with pytest.raises(WiringError, match=r"published on 'estop', which is not one of its"):
        CONTROLLER.published([(ep.ESTOP, EStop(stamp_ns=0, seq=0, engaged=True, source="x"))])
    with pytest.raises(WiringError, match="ControllerFeedback on 'controller/result'"):
        CONTROLLER.published([(ep.RESULT, _feedback())])
    with pytest.raises(WiringError, match="belongs to can_bridge, not to controller"):
        Wiring(ep.Service.CONTROLLER, messages, outputs=(ep.JOINTS,))
    with pytest.raises(WiringError, match="not in the endpoint table"):
        Wiring(ep.Service.CONTROLLER, messages, outputs=(THROWAWAY_TOPIC,))


@pytest.mark.parametrize(
    ("build", "field"),
    [
        (
            lambda: GoalResult(
                stamp_ns=0,
                seq=0,
                goal_id="g",
                kind="trajectory",
                status="preemted",
                cause="new_goal",
                reason="",
            ),
            "GoalResult/2.status: 'preemted' is not one of ['aborted', 'cancelled', "
            "'preempted', 'succeeded']",
        ),
        (
            lambda: TrajectoryGoal(goal_id="g", trajectory=_trajectory(), mode="thesys"),
            "TrajectoryGoal/1.mode: 'thesys' is not one of ['default', 'thesis']",
        ),
        (lambda: _bridge_state("runing"), "BridgeState/1.phase: 'runing' is not one of"),
    ],
)
def test_an_unknown_state_raises_when_the_message_is_built(build: Any, field: str) -> None:
    with pytest.raises(SchemaError) as err:
        build()
    assert field in str(err.value)


def _trajectory() -> Trajectory:
    rows = [[0.0] * 6, [0.0] * 6]
    return Trajectory(
        times=[0.0, 1.0],
        positions=rows,
        velocities=rows,
        accelerations=rows,
        via_xyz=[[0.0] * 3, [0.0] * 3],
        via_lines=[0, 0],
        preview_xyz=[],
    )


def _bridge_state(phase: str) -> BridgeState:
    return BridgeState(
        stamp_ns=0,
        seq=0,
        phase=phase,
        estop=False,
        cycles=0,
        period_ms=0.0,
        jitter_ms=0.0,
        reply_latency_ms=0.0,
        reply_latency_max_ms=0.0,
        missed_windows=0,
        stale_commands=0,
        resyncs=0,
        dropped_frames=0,
        duplicate_frames=0,
        garbled_frames=0,
        buffered_syncs=0,
        bad_payloads=0,
        detail="",
    )


def test_the_files_derived_from_the_table_are_current() -> None:
    """The supervisor document, the key table of docs/architecture.md and the routers'
    access control (``manus schemas --update`` rewrites them)."""
    from manus_stack.derived import derived, stale

    assert len([p for p, _ in derived() if p.exists()]) == 4
    assert stale() == [], "run: manus schemas --update"
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    assert ep.markdown_table(ep.TABLE) in text


def test_channel_types_come_from_the_table() -> None:
    types = channel_types()
    for e in ep.TABLE:
        if e.kind is ep.Kind.QUERYABLE:
            assert types[f"{e}#request"] is e.msg_type and types[f"{e}#reply"] is e.reply_type
        elif e.msg_type is not None:
            assert types[e.suffix] is e.msg_type
    assert len(types) == sum(
        2 if e.kind is ep.Kind.QUERYABLE else e.msg_type is not None for e in ep.TABLE
    )


# -- the deployed access control, checked against the owners of the table ------------------

ZENOH = ROOT / "deploy" / "zenoh"


def _policy(router: str) -> dict[str, Any]:
    config = zenoh.Config.from_file(str(ZENOH / f"router-{router}.json5"))
    found: dict[str, Any] = json.loads(config.get_json("access_control"))
    return found


def _allowed(policy: dict[str, Any], user: str, message: str, key: str) -> bool:
    subjects = {s["id"] for s in policy["subjects"] if user in (s.get("usernames") or [])}
    rules = {r for p in policy["policies"] if subjects & set(p["subjects"]) for r in p["rules"]}
    return any(
        rule["id"] in rules
        and rule["permission"] == "allow"
        and "ingress" in rule["flows"]
        and message in rule["messages"]
        and any(zenoh.KeyExpr(expr).includes(zenoh.KeyExpr(key)) for expr in rule["key_exprs"])
        for rule in policy["rules"]
    )


def test_the_panel_gets_the_supervisors_rights_on_its_keys_only() -> None:
    base = _policy("base")
    keys = Keys()
    for e in ep.TABLE:
        key = keys(e)
        for message in ("put", "query"):
            assert _allowed(base, "panel", message, key) == (
                e in PANEL_KEYS and _allowed(base, "supervisor", message, key)
            ), (e, message)
        assert not _allowed(base, "panel", "declare_queryable", key), e
    assert _allowed(base, "panel", "put", keys(ep.JOG))
    assert _allowed(base, "panel", "query", keys(ep.SUBMIT))


def test_every_owner_may_publish_and_declare_what_the_table_says_it_owns() -> None:
    policies = {r: _policy(r) for r in ("arm", "base")}
    home = {
        user: router
        for router, policy in policies.items()
        for s in policy["subjects"]
        for user in s.get("usernames") or []
        if not user.startswith("router-")
    }
    keys = Keys()
    for e in ep.TABLE:
        if e.owner not in home:
            continue  # anyone / each service / the recorder's file channel
        policy = policies[home[e.owner]]
        if e.kind is ep.Kind.PUBLICATION:
            assert _allowed(policy, e.owner, "put", keys(e)), (e, home[e.owner])
        if e.kind is ep.Kind.QUERYABLE:
            assert _allowed(policy, e.owner, "declare_queryable", keys(e)), e
            for part in ep.TRACE_PARTS:
                assert _allowed(policy, e.owner, "put", keys(e.trace(part))), (e, part)
    for user, router in home.items():  # every service holds its own liveliness tokens only
        own = _allowed(policies[router], user, "liveliness_token", keys.alive(user))
        assert own == (user != ep.SUPERVISOR and user not in DELEGATES), user
        for other in home:
            if other != user:
                theirs = keys.alive(other)
                assert not _allowed(policies[router], user, "liveliness_token", theirs)
    # The supervisor's API is open to the supervisor identity.
    for e in ep.TABLE:
        if e.audience is ep.Audience.SUPERVISOR and e.kind is ep.Kind.QUERYABLE:
            assert _allowed(policies["base"], "supervisor", "query", keys(e)), e
    # Motion commands: only the controller.
    for user, router in home.items():
        may = _allowed(policies[router], user, "put", keys(ep.JOINT_VELOCITY))
        assert may == (user == ep.Service.CONTROLLER), user
