"""The one Zenoh session factory every service uses.

Loopback only by default: a service is a ``client`` of a router on
``tcp/127.0.0.1:7447``, multicast scouting and gossip are off, and a peer or router that
is given no listen endpoint listens on ``tcp/127.0.0.1:0``. Real deployments override
the defaults in layers:

    defaults < Zenoh config file < environment < keyword arguments (command line)

Environment: ``MANUS_ZENOH_CONFIG`` (a Zenoh JSON5 config file), ``MANUS_ZENOH_MODE``
(client, peer, router), ``MANUS_ZENOH_CONNECT`` and ``MANUS_ZENOH_LISTEN`` (comma-separated
endpoints), ``MANUS_ZENOH_LEASE_MS``, ``MANUS_PREFIX``. Scouting stays off whatever the
config file says unless ``MANUS_ZENOH_SCOUTING=1`` (or ``scouting=True``) asks for it:
a lab network must never see this stack by accident.

Identity (two-computer deployment, ``docs/deployment.md``): ``MANUS_ZENOH_CREDENTIALS``
names a file whose first line is ``user:password`` (made by ``manus certs``, never in
the repository); the session logs in with it (``transport/auth/usrpwd``). A config file
of ``deploy/zenoh/`` that says ``metadata: { user: NAME }`` accepts only NAME's
credentials. ``MANUS_LAB_DIR`` points the config's ``/etc/manus/lab/...`` paths
(certificates, password tables) at another directory (a host without containers, a test).
"""

from __future__ import annotations

import argparse
import json
import os
import re
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import zenoh

from manus.errors import ConfigError

DEFAULT_ROUTER_ENDPOINT = "tcp/127.0.0.1:7447"
"""Where services look for the local router unless told otherwise."""

DEFAULT_PREFIX = "manus"
"""Root of every key expression of one arm."""

LAB_MOUNT = "/etc/manus/lab"
"""Where the deploy/zenoh files expect the lab credentials (``manus certs --out DIR``)."""

LAB_PATH_KEYS = (
    "transport/link/tls/root_ca_certificate",
    "transport/link/tls/listen_certificate",
    "transport/link/tls/listen_private_key",
    "transport/link/tls/connect_certificate",
    "transport/link/tls/connect_private_key",
    "transport/auth/usrpwd/dictionary_file",
)
"""Config entries that name lab files (moved by ``lab_dir``)."""

BLOCK_CLOSE_US = 50_000
"""How long a session (a router above all) waits for room in the queue of one link before
it closes that link [us] (Zenoh's default: 5 s). Every publisher of the stack uses
blocking congestion control, so that no live subscriber (the recorder) loses a message;
a subscriber that stops reading (SIGSTOP, a hung process) would otherwise hold the
router's delivery of those publishers to everyone else for up to 5 s: the heartbeat
comes late and the controller aborts the move. After 50 ms with a full queue (megabytes
behind) the stopped one is cut off, its tokens vanish, and it reconnects when it runs
again (``tests/test_stalled_subscriber.py``)."""

MODES = ("client", "peer", "router")
_PREFIX_RE = re.compile(r"^[A-Za-z0-9_\-]+(/[A-Za-z0-9_\-]+)*$")


@dataclass(frozen=True)
class ZenohSettings:
    """How a service reaches the bus.

    Attributes:
        mode: ``client`` (default, needs a router), ``peer`` or ``router``.
        connect: endpoints to connect to.
        listen: endpoints to listen on (peers and routers get ``tcp/127.0.0.1:0`` if empty).
        config_file: a Zenoh JSON5 configuration applied before the fields above.
        lease_ms: link lease [ms]: how soon a hung peer's liveliness tokens vanish.
        scouting: allow multicast scouting and gossip (off: loopback and explicit
            endpoints only).
        prefix: root of the key expressions (one arm per prefix).
        credentials_file: file whose first line is ``user:password`` (Zenoh usrpwd login).
        lab_dir: directory that replaces ``/etc/manus/lab`` in the config file's paths.
    """

    mode: str = "client"
    connect: tuple[str, ...] = (DEFAULT_ROUTER_ENDPOINT,)
    listen: tuple[str, ...] = ()
    config_file: str | None = None
    lease_ms: int = 1000
    scouting: bool = False
    prefix: str = DEFAULT_PREFIX
    extra: dict[str, Any] = field(default_factory=dict)
    credentials_file: str | None = None
    lab_dir: str | None = None

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ConfigError(f"zenoh mode {self.mode!r} is not one of {list(MODES)}")
        if not 100 <= self.lease_ms <= 600_000:
            raise ConfigError(f"zenoh lease {self.lease_ms} ms outside 100..600000 ms")
        if not _PREFIX_RE.match(self.prefix):
            raise ConfigError(
                f"key prefix {self.prefix!r} must be '/'-separated words of "
                "letters, digits, '_' or '-'"
            )
        for ep in (*self.connect, *self.listen):
            if "/" not in ep:
                raise ConfigError(f"zenoh endpoint {ep!r} must look like 'tcp/127.0.0.1:7447'")


def _split(value: str) -> tuple[str, ...]:
    return tuple(part.strip() for part in value.split(",") if part.strip())


def _lease_ms(value: str) -> int:
    try:
        return int(value)
    except ValueError as exc:
        raise ConfigError(f"MANUS_ZENOH_LEASE_MS={value!r} is not a whole number of ms") from exc


def _flag(value: str) -> bool:
    return value.strip().lower() in ("1", "true", "yes")


ENVIRONMENT: dict[str, tuple[str, Callable[[str], Any]]] = {
    "MANUS_ZENOH_CONFIG": ("config_file", str),
    "MANUS_ZENOH_MODE": ("mode", str),
    "MANUS_ZENOH_CONNECT": ("connect", _split),
    "MANUS_ZENOH_LISTEN": ("listen", _split),
    "MANUS_ZENOH_LEASE_MS": ("lease_ms", _lease_ms),
    "MANUS_ZENOH_SCOUTING": ("scouting", _flag),
    "MANUS_PREFIX": ("prefix", str),
    "MANUS_ZENOH_CREDENTIALS": ("credentials_file", str),
    "MANUS_LAB_DIR": ("lab_dir", str),
}
"""Environment variable -> (:class:`ZenohSettings` field, parser of its value); an empty
variable counts as unset."""


def settings_from_env(env: dict[str, str] | None = None, **overrides: Any) -> ZenohSettings:
    """Defaults < environment < ``overrides`` (keyword arguments that are not None)."""
    env = dict(os.environ) if env is None else env
    values: dict[str, Any] = {
        name: parse(env[var]) for var, (name, parse) in ENVIRONMENT.items() if env.get(var)
    }
    for key, value in overrides.items():
        if value is not None:
            values[key] = tuple(value) if key in ("connect", "listen") else value
    if "connect" not in values and (
        values.get("mode") in ("peer", "router") or values.get("config_file")
    ):
        # A peer or router connects to nobody by default; a config file keeps its own.
        values["connect"] = ()
    if values.get("config_file") and "mode" not in values:
        values["mode"] = _file_mode(Path(values["config_file"]))
    return ZenohSettings(**values)


def _file_mode(path: Path) -> str:
    """The mode a Zenoh config file sets (``client`` when it sets none)."""
    try:
        config = zenoh.Config.from_file(str(path))
    except Exception as exc:
        raise ConfigError(f"{path}: not a valid zenoh config: {exc}") from exc
    mode = json.loads(config.get_json("mode") or '"client"')
    return str(mode) if mode in MODES else "client"


def build_config(settings: ZenohSettings) -> zenoh.Config:
    """The Zenoh configuration for ``settings`` (see the module docstring for the layers)."""
    if settings.config_file:
        path = Path(settings.config_file)
        if not path.is_file():
            raise ConfigError(f"{path}: zenoh config file not found")
        try:
            config = zenoh.Config.from_file(str(path))
        except Exception as exc:  # zenoh raises its own ZError with the parser's message
            raise ConfigError(f"{path}: not a valid zenoh config: {exc}") from exc
    else:
        config = zenoh.Config()
    config.insert_json5("mode", json.dumps(settings.mode))
    if settings.connect or not settings.config_file:
        config.insert_json5("connect/endpoints", json.dumps(list(settings.connect)))
    if settings.mode == "client" and not settings.connect and not settings.config_file:
        raise ConfigError("a zenoh client needs at least one connect endpoint")
    listen = list(settings.listen)
    if not listen and settings.mode != "client" and not settings.config_file:
        listen = ["tcp/127.0.0.1:0"]
    if listen or settings.mode == "client":
        config.insert_json5("listen/endpoints", json.dumps(listen))
    if not settings.scouting:
        config.insert_json5("scouting/multicast/enabled", "false")
        config.insert_json5("scouting/gossip/enabled", "false")
    config.insert_json5("transport/link/tx/lease", str(settings.lease_ms))
    config.insert_json5("transport/link/tx/keep_alive", "4")
    config.insert_json5(
        "transport/link/tx/queue/congestion_control/block/wait_before_close",
        str(BLOCK_CLOSE_US),
    )
    for key, value in settings.extra.items():
        config.insert_json5(key, json.dumps(value))
    _apply_identity(config, settings)
    return config


def _lab_path(path: str, settings: ZenohSettings) -> str:
    if settings.lab_dir and (path == LAB_MOUNT or path.startswith(LAB_MOUNT + "/")):
        return str(Path(settings.lab_dir) / path[len(LAB_MOUNT) :].lstrip("/"))
    return path


def _apply_identity(config: zenoh.Config, settings: ZenohSettings) -> None:
    """Move lab paths to ``settings.lab_dir``; add the password of the configured user."""
    where = settings.config_file or "the zenoh settings"
    for key in LAB_PATH_KEYS:
        value = json.loads(config.get_json(key) or "null")
        if isinstance(value, str):
            moved = _lab_path(value, settings)
            if not Path(moved).is_file():
                raise ConfigError(
                    f"{where}: {key} = {moved!r}: file not found "
                    "(make the lab files with `manus certs --out DIR`)"
                )
            config.insert_json5(key, json.dumps(moved))
    wanted = json.loads(config.get_json("metadata") or "null")
    wanted = wanted.get("user") if isinstance(wanted, dict) else None
    if not settings.credentials_file:
        if wanted:
            raise ConfigError(
                f"{where}: metadata.user = {wanted!r} needs its credentials: set "
                "MANUS_ZENOH_CREDENTIALS (a USER.usrpwd file made by `manus certs --out DIR`)"
            )
        return
    path = Path(_lab_path(settings.credentials_file, settings))
    try:
        lines = path.read_text().splitlines()
    except OSError as exc:
        raise ConfigError(f"{path}: zenoh credentials file: {exc}") from exc
    user, sep, password = (lines[0] if lines else "").strip().partition(":")
    if not (user and sep and password):
        raise ConfigError(f"{path}:1: expected 'user:password' (zenoh credentials)")
    if wanted and user != wanted:
        raise ConfigError(f"{path}:1: user {user!r}, but {where} is the identity of {wanted!r}")
    config.insert_json5("transport/auth/usrpwd/user", json.dumps(user))
    config.insert_json5("transport/auth/usrpwd/password", json.dumps(password))


def add_bus_arguments(parser: argparse.ArgumentParser) -> None:
    """The bus options every service command takes (over the ``MANUS_ZENOH_*`` environment)."""
    parser.add_argument("--connect", nargs="+", metavar="ENDPOINT", help="router endpoint(s)")
    parser.add_argument("--mode", choices=MODES, help="zenoh mode")
    parser.add_argument("--prefix", help="key prefix of the arm (default: manus)")


def bus_settings(args: argparse.Namespace) -> ZenohSettings:
    """Defaults < environment < the options of :func:`add_bus_arguments`."""
    return settings_from_env(connect=args.connect, mode=args.mode, prefix=args.prefix)


def open_session(settings: ZenohSettings | None = None) -> zenoh.Session:
    """Open a Zenoh session (see :func:`build_config`).

    Raises:
        ConfigError: the settings are invalid or the session cannot be opened (for a
            client: no router answers at the connect endpoints).
    """
    settings = settings or settings_from_env()
    config = build_config(settings)
    zenoh.try_init_log_from_env()  # Zenoh's own log on stderr when RUST_LOG is set
    try:
        return zenoh.open(config)
    except Exception as exc:
        where = ", ".join(settings.connect) or ", ".join(settings.listen) or "?"
        raise ConfigError(
            f"cannot open a zenoh {settings.mode} session ({where}): {exc}; "
            "is the router running (`manus up` starts one)?"
        ) from exc


def router_settings(endpoint: str = DEFAULT_ROUTER_ENDPOINT, **kwargs: Any) -> ZenohSettings:
    """Settings of a loopback router listening on ``endpoint``."""
    return replace(ZenohSettings(mode="router", connect=(), listen=(endpoint,)), **kwargs)


def client_settings(endpoint: str = DEFAULT_ROUTER_ENDPOINT, **kwargs: Any) -> ZenohSettings:
    """Settings of a client of the router at ``endpoint``."""
    return replace(ZenohSettings(mode="client", connect=(endpoint,)), **kwargs)
