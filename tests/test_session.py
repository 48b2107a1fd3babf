"""The session factory keeps Zenoh on loopback, without multicast, unless configured."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from manus.errors import ConfigError
from manus.session import build_config, settings_from_env

PROBE = textwrap.dedent(
    """
    import ipaddress, json, sys, time
    import psutil
    from manus.session import open_session, router_settings, settings_from_env
    port = sys.argv[1]
    router = open_session(router_settings(f"tcp/127.0.0.1:{port}"))
    client = open_session(settings_from_env({"MANUS_ZENOH_CONNECT": f"tcp/127.0.0.1:{port}"}))
    peer = open_session(settings_from_env({"MANUS_ZENOH_MODE": "peer"}))
    pub = client.declare_publisher("probe/x")
    for _ in range(20):
        pub.put(b"x")
        time.sleep(0.05)
    out = []
    for c in psutil.Process().net_connections(kind="inet"):
        out.append({"type": int(c.type), "laddr": list(c.laddr),
                    "raddr": list(c.raddr) if c.raddr else []})
    print(json.dumps(out))
    for s in (peer, client, router):
        s.close()
    """
)


def test_default_sessions_use_loopback_only_and_no_udp(tmp_path: Path) -> None:
    from manus_stack.ports import free_port

    script = tmp_path / "probe.py"
    script.write_text(PROBE)
    run = subprocess.run(
        [sys.executable, str(script), str(free_port())],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
        env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(Path(__file__).parent.parent)},
    )
    sockets = json.loads(run.stdout.strip().splitlines()[-1])
    assert sockets, "the probe should see its own TCP sockets"
    import ipaddress
    import socket

    for s in sockets:
        # No UDP at all: multicast scouting would need a UDP socket on 224.0.0.224:7446.
        assert s["type"] == socket.SOCK_STREAM, f"unexpected UDP socket {s}"
        for addr in (s["laddr"], s["raddr"]):
            if addr:
                assert ipaddress.ip_address(addr[0]).is_loopback, f"non-loopback socket {s}"


def test_config_turns_scouting_off_and_listens_on_loopback() -> None:
    peer = build_config(settings_from_env({"MANUS_ZENOH_MODE": "peer"}))
    assert json.loads(peer.get_json("scouting/multicast/enabled")) is False
    assert json.loads(peer.get_json("scouting/gossip/enabled")) is False
    assert json.loads(peer.get_json("listen/endpoints")) == ["tcp/127.0.0.1:0"]
    client = build_config(settings_from_env({}))
    assert json.loads(client.get_json("connect/endpoints")) == ["tcp/127.0.0.1:7447"]
    assert json.loads(client.get_json("scouting/multicast/enabled")) is False


def test_config_file_then_environment_layers(tmp_path: Path) -> None:
    f = tmp_path / "z.json5"
    f.write_text(
        '{ mode: "peer", listen: { endpoints: ["tcp/127.0.0.1:0"] }, '
        "scouting: { multicast: { enabled: true } } }"
    )
    s = settings_from_env({"MANUS_ZENOH_CONFIG": str(f)})
    assert s.mode == "peer"
    cfg = build_config(s)
    # Scouting stays off even though the file asks for it, unless explicitly allowed.
    assert json.loads(cfg.get_json("scouting/multicast/enabled")) is False
    s = settings_from_env(
        {
            "MANUS_ZENOH_CONFIG": str(f),
            "MANUS_ZENOH_MODE": "client",
            "MANUS_ZENOH_CONNECT": "tcp/127.0.0.1:9999",
            "MANUS_PREFIX": "lab/arm",
        }
    )
    assert (s.mode, s.connect, s.prefix) == ("client", ("tcp/127.0.0.1:9999",), "lab/arm")


@pytest.mark.parametrize(
    ("env", "match"),
    [
        ({"MANUS_ZENOH_MODE": "server"}, "zenoh mode 'server' is not one of"),
        ({"MANUS_ZENOH_LEASE_MS": "soon"}, "MANUS_ZENOH_LEASE_MS='soon' is not a whole number"),
        ({"MANUS_PREFIX": "bad prefix"}, "key prefix 'bad prefix' must be"),
        ({"MANUS_ZENOH_CONNECT": "localhost"}, "endpoint 'localhost' must look like"),
        ({"MANUS_ZENOH_CONFIG": "/nonexistent.json5"}, "not a valid zenoh config|not found"),
    ],
)
def test_bad_settings_are_named(env: dict[str, str], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        build_config(settings_from_env(env))
