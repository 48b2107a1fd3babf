"""Loopback ports for a local stack's router (``manus up``, the tests, the benches)."""

from __future__ import annotations

import socket


def free_port() -> int:
    """A TCP port on 127.0.0.1 that was free a moment ago (for a loopback router)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def endpoint_port(endpoint: str) -> tuple[str, int]:
    """``tcp/127.0.0.1:7447`` -> ("127.0.0.1", 7447)."""
    host, _, port = endpoint.split("/", 1)[-1].rpartition(":")
    return host.strip("[]"), int(port)


def port_in_use(endpoint: str) -> bool:
    """Something already listens on the endpoint."""
    host, port = endpoint_port(endpoint)
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.settimeout(0.2)
        return s.connect_ex((host, port)) == 0
