"""compose.yaml and the Zenoh files it mounts: consistent, loopback-first, no scouting.

No Docker engine runs here, so the file is checked as data: every service runs a
`manus` subcommand that exists, every config file it names exists and loads as a Zenoh
configuration with multicast scouting and gossip off, clients stay on loopback, every
service has its own identity (config file + credentials of the same user, known to its
computer's router), and only the routers cross the network, over TLS.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import pytest
import yaml
import zenoh

from manus.certs import ARM_USERS, BASE_USERS
from manus.realtime import CAN_EDGE, DEFAULT
from manus_stack.cli import COMMANDS, build_parser

ROOT = Path(__file__).resolve().parent.parent
ZENOH_DIR = ROOT / "deploy" / "zenoh"
MOUNT = "/etc/manus/zenoh"
LAB = "/etc/manus/lab"


def _compose() -> dict[str, Any]:
    data = yaml.safe_load((ROOT / "compose.yaml").read_text())
    assert isinstance(data, dict)
    return data


def _host_path(container_path: str) -> Path:
    assert container_path.startswith(MOUNT + "/"), container_path
    return ZENOH_DIR / container_path.removeprefix(MOUNT + "/")


def test_every_service_is_on_a_computer_and_runs_a_real_command() -> None:
    services = _compose()["services"]
    profiles = {name: set(s.get("profiles", [])) for name, s in services.items()}
    arm = {n for n, p in profiles.items() if "arm" in p}
    base = {n for n, p in profiles.items() if "base" in p}
    assert {"router-arm", "can-bridge", "guardian", "controller"} <= arm
    assert {"router-base", "planner", "sequencer", "recorder"} <= base
    assert not arm & base
    for name, service in services.items():
        assert profiles[name], f"{name}: every service belongs to a computer's profile"
        command = service["command"]
        assert command[0] in COMMANDS, f"{name}: `manus {command[0]}` is not a command"
        if command[0] == "router":
            continue
        env = service["environment"]
        assert _host_path(env["MANUS_ZENOH_CONFIG"]).is_file()
    for name in arm | base:
        for dep in services[name].get("depends_on", []):
            assert profiles[dep] & profiles[name], f"{name} depends on {dep} of another computer"


def _routers() -> list[Path]:
    services = _compose()["services"]
    paths = []
    for s in services.values():
        if s["command"][0] == "router":
            paths.append(_host_path(s["command"][s["command"].index("--config") + 1]))
    return paths


def _get(config: zenoh.Config, key: str) -> Any:
    return json.loads(config.get_json(key) or "null")


def test_every_service_has_its_own_identity_known_to_its_router() -> None:
    services = _compose()["services"]
    users: dict[str, str] = {}
    for name, service in services.items():
        env = service.get("environment", {})
        is_router = service["command"][0] == "router"
        config_path = (
            _host_path(service["command"][service["command"].index("--config") + 1])
            if is_router
            else _host_path(env["MANUS_ZENOH_CONFIG"])
        )
        config = zenoh.Config.from_file(str(config_path))
        metadata = _get(config, "metadata")
        user = metadata.get("user") if isinstance(metadata, dict) else None
        if name == "router-arm":
            assert user is None and "MANUS_ZENOH_CREDENTIALS" not in env
            continue
        assert user, f"{config_path.name}: metadata.user names the identity"
        assert env["MANUS_ZENOH_CREDENTIALS"] == f"{LAB}/{user}.usrpwd", name
        assert _get(config, "transport/auth/usrpwd/password") is None, "no password in git"
        assert user not in users, f"{name} and {users.get(user)} share the user {user!r}"
        users[user] = name
        # The user is in the table of the router its computer's clients log in to.
        known = ARM_USERS if set(service["profiles"]) & {"arm", "sim"} else BASE_USERS
        if name == "router-base":
            known = ARM_USERS  # it logs in to the arm's router
        assert user in known, f"{name}: user {user!r} unknown to its router ({known})"
        assert {"./deploy/zenoh:/etc/manus/zenoh:ro", f"${{MANUS_LAB_DIR:-./lab}}:{LAB}:ro"} <= set(
            service["volumes"]
        ), name


def test_routers_link_over_mutual_tls_with_access_control() -> None:
    arm = zenoh.Config.from_file(str(ZENOH_DIR / "router-arm.json5"))
    base = zenoh.Config.from_file(str(ZENOH_DIR / "router-base.json5"))
    assert _get(arm, "listen/endpoints") == ["tcp/127.0.0.1:7447", "tls/[::]:7448"]
    assert _get(base, "connect/endpoints") == ["tls/manus-arm:7448"]
    for config in (arm, base):
        assert _get(config, "transport/link/tls/enable_mtls") is True
        assert _get(config, "transport/link/tls/root_ca_certificate") == f"{LAB}/ca.pem"
        assert _get(config, "access_control/enabled") is True
        assert _get(config, "access_control/default_permission") == "deny"
        assert str(_get(config, "transport/auth/usrpwd/dictionary_file")).startswith(LAB + "/")


@pytest.mark.parametrize(
    "path", sorted(ZENOH_DIR.glob("**/*.json5")), ids=lambda p: str(p.relative_to(ZENOH_DIR))
)
def test_zenoh_files_load_with_scouting_off(path: Path) -> None:
    config = zenoh.Config.from_file(str(path))
    assert json.loads(config.get_json("scouting/multicast/enabled")) is False
    assert json.loads(config.get_json("scouting/gossip/enabled")) is False


def test_clients_stay_on_loopback_and_only_routers_cross_the_network() -> None:
    client = zenoh.Config.from_file(str(ZENOH_DIR / "client.json5"))
    assert json.loads(client.get_json("mode")) == "client"
    assert json.loads(client.get_json("connect/endpoints")) == ["tcp/127.0.0.1:7447"]
    routers = _routers()
    assert {p.name for p in routers} == {"router-arm.json5", "router-base.json5"}
    base = zenoh.Config.from_file(str(ZENOH_DIR / "router-base.json5"))
    assert json.loads(base.get_json("listen/endpoints")) == ["tcp/127.0.0.1:7447"]
    for path in sorted((ZENOH_DIR / "services").glob("*.json5")):
        config = zenoh.Config.from_file(str(path))
        assert _get(config, "mode") == "client", path.name
        assert _get(config, "connect/endpoints") == ["tcp/127.0.0.1:7447"], path.name
        assert _get(config, "listen/endpoints") == [], path.name


def test_no_credentials_in_the_repository() -> None:
    for path in (ROOT / "deploy").rglob("*"):
        if path.is_file():
            assert path.suffix not in (".key", ".usrpwd", ".pem"), f"{path}: credentials in git"
            assert "PRIVATE KEY" not in path.read_text(errors="replace"), path
    ignored = (ROOT / ".gitignore").read_text().split()
    assert "/lab/" in ignored, "./lab (manus certs --out ./lab) must stay out of git"


def _takes_realtime(command: str) -> bool:
    parser = build_parser(command)
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return any("--realtime" in a.option_strings for a in sub.choices[command]._actions)


def test_the_services_on_the_60_ms_path_may_raise_their_priority() -> None:
    """The commands that take --realtime (manus.realtime) are the ones on the arm's loop;
    their containers permit a real-time priority as high as the defaults (ulimits rtprio:
    Docker does not make cap_add effective for the image's user; SYS_NICE for root)."""
    services = _compose()["services"]
    commands = {s["command"][0] for s in services.values()}
    realtime = {c for c in commands if _takes_realtime(c)}
    assert realtime == {"router", "bridge", "guardian", "controller", "sim", "sequencer"}
    for name, service in services.items():
        if service["command"][0] not in realtime:
            assert "cap_add" not in service and "ulimits" not in service, name
            continue
        assert "SYS_NICE" in service["cap_add"], name
        assert service["ulimits"]["rtprio"] >= max(DEFAULT.level, CAN_EDGE.level), name
        assert service["environment"]["MANUS_REALTIME"] == "${MANUS_REALTIME:-}", name
