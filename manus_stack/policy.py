"""The deployed access control, generated from the endpoint table: no impostors.

Every key has an owner (:mod:`schemas.endpoints`), so each Zenoh identity of the
two-computer deployment (one user name per service, plus ``supervisor``; the other
computer's router by its certificate and user name) gets exactly what it owns:

- ``put`` / ``delete`` on its own publications and on the ``trace/`` mirrors of its own
  queryables (``estop``: every identity);
- ``declare_queryable`` and ``reply`` on its own queryables only: a rogue client cannot
  answer ``planner/plan`` in the planner's place (of a per-service root such as
  ``health``: on ``health/<itself>`` only);
- ``liveliness_token`` on ``alive/<itself>``, ``where/<itself>/**`` and
  ``disabled/<itself>/**`` only: it cannot make the sequencer believe a dead controller lives;
- ``query`` on the queryables open to it (``Endpoint.clients``; by default every
  identity);
- everybody may subscribe, watch tokens and receive (``egress``);
- an identity that acts for another on some keys only (:data:`DELEGATES`: the panel for
  the supervisor) gets the other's rights on those keys and nothing else.

A router enforces this for its own clients; the link from the other computer's router
(subject ``router-<other>``) gets the union of what that computer's identities own, so a
base-computer client is checked by the base router once and its traffic is let through on
the arm side as the base router's. Key expressions start with ``**/`` so that any prefix
(one arm per prefix) works.

``python -m manus_stack.policy`` rewrites the ``access_control`` block of
``deploy/zenoh/router-arm.json5`` and ``router-base.json5`` between their ``BEGIN`` and
``END`` marker lines; ``--check`` exits 1 when a file is not current (a test runs it).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from manus.certs import ARM_USERS, BASE_USERS
from manus_stack.panel.keys import PANEL_KEYS
from schemas.endpoints import (
    ALIVE,
    ANYONE,
    DISABLED,
    EACH_SERVICE,
    SUPERVISOR,
    TABLE,
    TRACE_PARTS,
    WHERE,
    Endpoint,
    Kind,
)

ZENOH_DIR = Path(__file__).resolve().parent.parent / "deploy" / "zenoh"
BEGIN = "  // BEGIN access control, generated from schemas/endpoints.py by"
END = "  // END access control"

COMPUTERS: dict[str, tuple[str, ...]] = {
    "arm": tuple(u for u in ARM_USERS if not u.startswith("router-")),
    "base": tuple(u for u in BASE_USERS if not u.startswith("router-")),
}
"""The identities whose clients each computer's router serves."""

EVERYBODY_READS = ("declare_subscriber", "declare_liveliness_subscriber", "liveliness_query")

DELEGATES: dict[str, tuple[str, tuple[Endpoint, ...]]] = {
    "panel": (SUPERVISOR, PANEL_KEYS),
}
"""identity -> (whom it acts for, on which keys): ``manus panel`` (docs/panel.md) publishes
and queries as the supervisor does, on the keys it uses only (not the scene, the flight
recorder's trigger or a replay's control); it holds no liveliness token."""


def _key(suffix: str) -> str:
    return f"**/{suffix}"


def permissions(identity: str) -> dict[str, list[str]]:
    """Message kind -> key expressions ``identity`` may send (ingress), from the table."""
    if identity in DELEGATES:
        principal, keys = DELEGATES[identity]
        own = {_key(k) for k in keys}
        full = permissions(principal)
        return {
            "put": [k for k in full["put"] if k in own],
            "declare_queryable": [],
            "reply": [],
            "query": [k for k in full["query"] if k in own],
            "liveliness_token": [],
        }
    put: list[str] = []
    declare: list[str] = []
    query: list[str] = []
    for e in TABLE:
        if e.kind is Kind.PUBLICATION and e.owner in (identity, ANYONE):
            put.append(_key(e))
        if e.kind is Kind.QUERYABLE:
            if e.owner == identity:
                declare.append(_key(e))
                put += [_key(e.trace(part)) for part in TRACE_PARTS]
            elif e.owner == EACH_SERVICE and identity != "supervisor":
                declare.append(_key(f"{e}/{identity}"))  # its own one (health/<itself>)
            if _may_query(e, identity):
                query.append(_key(e) if e.owner != EACH_SERVICE else _key(f"{e}/**"))
    tokens = [_key(f"{ALIVE}/{identity}"), _key(f"{WHERE}/{identity}/**")]
    tokens.append(_key(f"{DISABLED}/{identity}/**"))
    return {
        "put": put,
        "declare_queryable": declare,
        "reply": declare,
        "query": query,
        "liveliness_token": tokens if identity != "supervisor" else [],
    }


def _may_query(e: Endpoint, identity: str) -> bool:
    return e.clients is None or identity in e.clients or identity == e.owner


def _rule(rule_id: str, messages: list[str], keys: list[str]) -> dict[str, Any]:
    return {
        "id": rule_id,
        "permission": "allow",
        "flows": ["ingress"],
        "messages": messages,
        "key_exprs": sorted(set(keys)),
    }


def access_control(router: str) -> dict[str, Any]:
    """The ``access_control`` section of router ``arm`` or ``base``."""
    other = "base" if router == "arm" else "arm"
    rules: list[dict[str, Any]] = [
        {
            "id": "deliver",
            "permission": "allow",
            "flows": ["egress"],
            "messages": [
                "put",
                "delete",
                "query",
                "reply",
                "declare_subscriber",
                "declare_queryable",
                "liveliness_token",
                "declare_liveliness_subscriber",
                "liveliness_query",
            ],
            "key_exprs": ["**"],
        },
        _rule("read", list(EVERYBODY_READS), ["**"]),
    ]
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    members: list[tuple[str, tuple[str, ...]]] = [(user, (user,)) for user in COMPUTERS[router]]
    members.append((f"router-{other}", COMPUTERS[other]))
    for subject, identities in members:
        allowed: dict[str, list[str]] = {}
        for identity in identities:
            for message, keys in permissions(identity).items():
                allowed.setdefault(message, []).extend(keys)
        names: list[str] = ["read"]
        groups = (
            ("publish", ["put", "delete"], allowed["put"]),
            ("answer", ["declare_queryable", "reply"], allowed["declare_queryable"]),
            ("query", ["query"], allowed["query"]),
            ("tokens", ["liveliness_token"], allowed["liveliness_token"]),
        )
        for group, messages, keys in groups:
            if keys:
                rules.append(_rule(f"{subject}-{group}", messages, keys))
                names.append(f"{subject}-{group}")
        entry: dict[str, Any] = {"id": subject}
        if subject.startswith("router-"):
            # The link: the other router's certificate; the base router also logs in to
            # the arm router with its password (it is the one that connects).
            entry["cert_common_names"] = [subject]
        if subject in ARM_USERS or subject in BASE_USERS:
            entry["usernames"] = [subject]
        subjects.append(entry)
        policies.append({"rules": names, "subjects": [subject]})
    for rule in rules:  # every subject receives everything
        if rule["id"] == "deliver":
            policies.insert(0, {"rules": ["deliver"], "subjects": [s["id"] for s in subjects]})
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }


def render(router: str, text: str) -> str:
    """``text`` (a router file) with its generated block replaced.

    Raises:
        ValueError: the file has no marker lines.
    """
    lines = text.split("\n")
    try:
        begin = next(i for i, line in enumerate(lines) if line.startswith(BEGIN))
        end = next(i for i, line in enumerate(lines) if line.startswith(END))
    except StopIteration:
        raise ValueError(f"router-{router}.json5: no {BEGIN!r} ... {END!r} lines") from None
    body = _dumps(access_control(router)).split("\n")
    block = [f"{BEGIN} python -m manus_stack.policy"]
    block.append("  access_control: " + body[0])
    block += ["  " + line for line in body[1:-1]]
    block.append("  " + body[-1] + ",")
    block.append(END)
    return "\n".join([*lines[:begin], *block, *lines[end + 1 :]])


def _dumps(value: Any, indent: str = "") -> str:
    """JSON with one rule per block and each list of names on one line."""
    inner = indent + "  "
    if isinstance(value, dict):
        items = [f"{inner}{json.dumps(k)}: {_dumps(v, inner)}" for k, v in value.items()]
        return "{\n" + ",\n".join(items) + f"\n{indent}}}"
    if isinstance(value, list) and all(isinstance(v, str) for v in value):
        return json.dumps(value)
    if isinstance(value, list):
        return "[\n" + ",\n".join(inner + _dumps(v, inner) for v in value) + f"\n{indent}]"
    return json.dumps(value)


def main(argv: list[str] | None = None) -> int:
    """Rewrite (or ``--check``) the routers' access control."""
    parser = argparse.ArgumentParser(prog="python -m manus_stack.policy", description=__doc__)
    parser.add_argument("--check", action="store_true", help="exit 1 if a file is not current")
    args = parser.parse_args(argv)
    stale = []
    for router in COMPUTERS:
        path = ZENOH_DIR / f"router-{router}.json5"
        text = path.read_text(encoding="utf-8")
        new = render(router, text)
        if new != text:
            stale.append(path.name)
            if not args.check:
                path.write_text(new, encoding="utf-8")
    if args.check and stale:
        print(f"not current: {', '.join(stale)} (python -m manus_stack.policy)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
