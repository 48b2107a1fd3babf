"""compose.yaml and the Zenoh files it mounts: consistent, loopback-first, no scouting.

No Docker engine runs here, so the file is checked as data: every service runs a
`manus` subcommand that exists, every config file it names exists and loads as a Zenoh
configuration with multicast scouting and gossip off, and clients stay on loopback.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import yaml
import zenoh

from manus_stack.cli import COMMANDS

ROOT = Path(__file__).resolve().parent.parent
ZENOH_DIR = ROOT / "deploy" / "zenoh"
MOUNT = "/etc/manus/zenoh"


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
    assert {"router-arm", "can-bridge", "controller"} <= arm
    assert {"router-base", "planner", "sequencer", "recorder"} <= base
    assert not arm & base
    for name, service in services.items():
        assert profiles[name], f"{name}: every service belongs to a computer's profile"
        if service.get("image", "").startswith("eclipse/zenoh"):
            continue
        command = service["command"]
        assert command[0] in COMMANDS, f"{name}: `manus {command[0]}` is not a command"
        env = service["environment"]
        assert _host_path(env["MANUS_ZENOH_CONFIG"]).is_file()
    for name in arm | base:
        for dep in services[name].get("depends_on", []):
            assert profiles[dep] & profiles[name], f"{name} depends on {dep} of another computer"


def _routers() -> list[Path]:
    services = _compose()["services"]
    paths = []
    for s in services.values():
        if s.get("image", "").startswith("eclipse/zenoh"):
            paths.append(_host_path(s["command"][s["command"].index("--config") + 1]))
    return paths


@pytest.mark.parametrize("path", sorted(ZENOH_DIR.glob("*.json5")), ids=lambda p: p.name)
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
    assert json.loads(base.get_json("connect/endpoints")) == ["tcp/manus-arm:7447"]
