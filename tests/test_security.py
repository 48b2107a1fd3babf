"""TLS between the routers and access control, with the deploy/zenoh files themselves.

Every test makes a fresh lab (``manus.certs.write_lab``) in ``tmp_path`` and opens the
committed configs with ``lab_dir`` pointing there, on loopback ports of its own (the
TLS listener of the arm router moves from ``[::]:7448`` to ``127.0.0.1:<free>``).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import zenoh

from manus.certs import write_lab
from manus.errors import ConfigError
from manus.session import ZenohSettings, build_config, open_session, settings_from_env
from manus_stack.ports import free_port

ZENOH_DIR = Path(__file__).resolve().parent.parent / "deploy" / "zenoh"
CMD = "manus/cmd/joint_velocity"
WAIT_S = 5.0
"""Bound on every wait for something that should arrive [s]."""
QUIET_S = 0.5
"""How long nothing more must arrive after the allowed sample did [s]."""


class Lab:
    """A lab directory, the arm router's two ports and the sessions a test opened."""

    def __init__(self, root: Path) -> None:
        self.dir = root / "lab"
        write_lab(self.dir, days=1)
        self.arm_tcp = f"tcp/127.0.0.1:{free_port()}"
        self.arm_tls = f"tls/localhost:{free_port()}"
        self.base_tcp = f"tcp/127.0.0.1:{free_port()}"
        self.sessions: list[zenoh.Session] = []

    def settings(self, file: str, lab: Path | None = None, **kw: object) -> ZenohSettings:
        lab = lab or self.dir
        user = file.removeprefix("services/").removesuffix(".json5")
        credentials = lab / f"{user}.usrpwd"
        return settings_from_env(
            {},
            config_file=str(ZENOH_DIR / file),
            lab_dir=str(lab),
            credentials_file=str(credentials) if credentials.is_file() else None,
            **kw,
        )

    def open(self, file: str, lab: Path | None = None, **kw: object) -> zenoh.Session:
        session = open_session(self.settings(file, lab, **kw))
        self.sessions.append(session)
        return session

    def router_arm(self) -> zenoh.Session:
        return self.open("router-arm.json5", listen=(self.arm_tcp, self.arm_tls))

    def router_base(self, lab: Path | None = None) -> zenoh.Session:
        return self.open("router-base.json5", lab, listen=(self.base_tcp,), connect=(self.arm_tls,))

    def client(self, service: str, endpoint: str) -> zenoh.Session:
        return self.open(f"services/{service}.json5", connect=(endpoint,))

    def close(self) -> None:
        for session in reversed(self.sessions):
            session.close()


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[Lab]:
    the_lab = Lab(tmp_path)
    try:
        yield the_lab
    finally:
        the_lab.close()


class Inbox:
    """Payloads received by a subscriber, with a bounded wait."""

    def __init__(self, session: zenoh.Session, key: str) -> None:
        self.items: list[bytes] = []
        self._cond = threading.Condition()
        self._sub = session.declare_subscriber(key, self._on)

    def _on(self, sample: zenoh.Sample) -> None:
        with self._cond:
            self.items.append(sample.payload.to_bytes())
            self._cond.notify_all()

    def wait_for(self, payload: bytes, timeout: float = WAIT_S) -> bool:
        with self._cond:
            return self._cond.wait_for(lambda: payload in self.items, timeout)


def _until(predicate: Callable[[], bool], timeout: float = WAIT_S) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.05)
    return predicate()


def _put_until_received(pub: zenoh.Session, inbox: Inbox, key: str, payload: bytes) -> bool:
    """Publish ``payload`` every 0.1 s until it arrives (routes take a moment to form)."""
    end = time.monotonic() + WAIT_S
    while time.monotonic() < end:
        pub.put(key, payload)
        if inbox.wait_for(payload, timeout=0.1):
            return True
    return False


ROGUE_KEYS = (CMD, "manus/cmd/*", "manus/**", "*/cmd/joint_velocity", "manus/cmd/joint_velocity/**")


def test_only_the_controller_may_publish_velocity_commands(lab: Lab) -> None:
    lab.router_arm()
    bridge = lab.client("can_bridge", lab.arm_tcp)
    inbox = Inbox(bridge, CMD)
    controller = lab.client("controller", lab.arm_tcp)
    rogue = lab.client("simulator", lab.arm_tcp)  # a real identity, but not the controller's
    assert _put_until_received(controller, inbox, CMD, b"controller-1")
    for key in ROGUE_KEYS:
        rogue.put(key, b"rogue " + key.encode())
    publisher = rogue.declare_publisher(CMD)
    publisher.put(b"rogue publisher")
    controller.put(CMD, b"controller-2")
    assert inbox.wait_for(b"controller-2")
    time.sleep(QUIET_S)
    assert not [p for p in inbox.items if p.startswith(b"rogue")], inbox.items
    # The simulator's own publication goes through: the rules follow the owners.
    truth = Inbox(bridge, "manus/sim/truth")
    assert _put_until_received(rogue, truth, "manus/sim/truth", b"truth ok")


def test_without_or_with_a_wrong_password_no_session(lab: Lab, tmp_path: Path) -> None:
    lab.router_arm()
    with pytest.raises(ConfigError, match=r"metadata.user = 'controller' needs its credentials"):
        build_config(
            settings_from_env(
                {}, config_file=str(ZENOH_DIR / "services/controller.json5"), lab_dir=str(lab.dir)
            )
        )
    with pytest.raises(ConfigError, match=r"user 'planner', but .* identity of 'controller'"):
        build_config(
            settings_from_env(
                {},
                config_file=str(ZENOH_DIR / "services/controller.json5"),
                credentials_file=str(lab.dir / "planner.usrpwd"),
            )
        )
    wrong = tmp_path / "wrong.usrpwd"
    wrong.write_text("controller:not-the-password\n")
    settings = settings_from_env(
        {},
        config_file=str(ZENOH_DIR / "services/controller.json5"),
        credentials_file=str(wrong),
        connect=(lab.arm_tcp,),
    )
    with pytest.raises(ConfigError, match="cannot open a zenoh client session"):
        open_session(settings)
    anonymous = settings_from_env({"MANUS_ZENOH_CONNECT": lab.arm_tcp})
    with pytest.raises(ConfigError, match="cannot open a zenoh client session"):
        open_session(anonymous)


def _answering(session: zenoh.Session, key: str) -> zenoh.Queryable[None]:
    def on_query(query: zenoh.Query) -> None:
        query.reply(query.key_expr, b"accepted " + str(query.key_expr).encode())

    return session.declare_queryable(key, on_query)


def _replies(session: zenoh.Session, key: str, timeout: float = 1.0) -> list[bytes]:
    out = []
    for reply in session.get(key, timeout=timeout):
        if reply.ok is not None:
            out.append(reply.ok.payload.to_bytes())
    return out


def test_only_sequencer_and_supervisor_submit_tasks(lab: Lab) -> None:
    lab.open("router-base.json5", listen=(lab.base_tcp,), connect=())
    sequencer = lab.client("sequencer", lab.base_tcp)
    keep = [
        _answering(sequencer, f"manus/sequencer/{name}") for name in ("submit", "control", "status")
    ]
    supervisor = lab.client("supervisor", lab.base_tcp)
    planner = lab.client("planner", lab.base_tcp)
    assert _until(lambda: bool(_replies(supervisor, "manus/sequencer/submit", 0.3)))
    assert _replies(supervisor, "manus/sequencer/control") == [b"accepted manus/sequencer/control"]
    # The planner reaches the sequencer (status answers) but cannot submit or control,
    # not even through a wildcard.
    assert _replies(planner, "manus/sequencer/status") == [b"accepted manus/sequencer/status"]
    for key in (
        "manus/sequencer/submit",
        "manus/sequencer/control",
        "manus/sequencer/*",
        "manus/**",
    ):
        assert _replies(planner, key) == [], key
    assert len(keep) == 3


def test_only_the_supervisor_may_jog(lab: Lab) -> None:
    lab.open("router-base.json5", listen=(lab.base_tcp,), connect=())
    sequencer = lab.client("sequencer", lab.base_tcp)  # stands in for the arm's side
    inbox = Inbox(sequencer, "manus/jog")
    supervisor = lab.client("supervisor", lab.base_tcp)
    planner = lab.client("planner", lab.base_tcp)
    assert _put_until_received(supervisor, inbox, "manus/jog", b"supervisor-1")
    for key in ("manus/jog", "manus/*", "manus/**", "*/jog"):
        planner.put(key, b"rogue " + key.encode())
    supervisor.put("manus/jog", b"supervisor-2")
    assert inbox.wait_for(b"supervisor-2")
    time.sleep(QUIET_S)
    assert not [p for p in inbox.items if p.startswith(b"rogue")], inbox.items


def test_the_panel_jogs_stops_and_runs_tasks_and_nothing_more(lab: Lab) -> None:
    """``manus panel``'s identity acts for the supervisor on its own keys only."""
    lab.open("router-base.json5", listen=(lab.base_tcp,), connect=())
    sequencer = lab.client("sequencer", lab.base_tcp)
    planner = lab.client("planner", lab.base_tcp)
    keep = [_answering(sequencer, f"manus/sequencer/{name}") for name in ("submit", "control")]
    keep.append(_answering(planner, "manus/planner/scene"))
    jog, estop = Inbox(sequencer, "manus/jog"), Inbox(sequencer, "manus/estop")
    heartbeat = Inbox(sequencer, "manus/heartbeat")
    panel = lab.client("panel", lab.base_tcp)
    supervisor = lab.client("supervisor", lab.base_tcp)
    assert _put_until_received(panel, jog, "manus/jog", b"panel")
    assert _put_until_received(panel, estop, "manus/estop", b"STOP")
    assert _until(lambda: bool(_replies(panel, "manus/sequencer/submit", 0.3)))
    assert _replies(panel, "manus/sequencer/control") == [b"accepted manus/sequencer/control"]
    # not the supervisor's other rights (the scene), nor a service's (the heartbeat)
    assert _replies(supervisor, "manus/planner/scene") == [b"accepted manus/planner/scene"]
    assert _replies(panel, "manus/planner/scene") == []
    panel.put("manus/heartbeat", b"rogue")
    time.sleep(QUIET_S)
    assert heartbeat.items == []
    assert len(keep) == 3


@pytest.mark.parametrize("host", ["localhost", "127.0.0.1"])
def test_routers_linked_over_tls_pass_samples_both_ways(lab: Lab, host: str) -> None:
    lab.arm_tls = lab.arm_tls.replace("localhost", host)  # a DNS name and an IP address SAN
    arm = lab.router_arm()
    lab.router_base()
    assert _until(lambda: len(list(arm.info.routers_zid())) == 1), "no TLS link"
    recorder = lab.client("recorder", lab.base_tcp)
    commands = Inbox(recorder, CMD)
    controller = lab.client("controller", lab.arm_tcp)
    assert _put_until_received(controller, commands, CMD, b"over tls")
    bridge = lab.client("can_bridge", lab.arm_tcp)
    heartbeat = Inbox(bridge, "manus/heartbeat")
    sequencer = lab.client("sequencer", lab.base_tcp)
    assert _put_until_received(sequencer, heartbeat, "manus/heartbeat", b"alive")
    # Liveliness (alive/, where/: `manus status`) crosses the link and the access control.
    token = controller.liveliness().declare_token("manus/where/controller/arm/1")
    supervisor = lab.client("supervisor", lab.base_tcp)

    def alive() -> list[str]:
        replies = supervisor.liveliness().get("manus/where/**", timeout=0.5)
        return [str(r.ok.key_expr) for r in replies if r.ok is not None]

    assert _until(lambda: alive() == ["manus/where/controller/arm/1"])
    token.undeclare()
    # A base service cannot command the arm, whatever router it goes through.
    arm_commands = Inbox(bridge, CMD)
    lab.client("planner", lab.base_tcp).put(CMD, b"rogue from base")
    assert _put_until_received(controller, arm_commands, CMD, b"after rogue")
    time.sleep(QUIET_S)
    assert b"rogue from base" not in arm_commands.items


def test_router_link_with_another_ca_fails(lab: Lab, tmp_path: Path) -> None:
    other = tmp_path / "other-lab"
    write_lab(other, days=1)
    arm = lab.router_arm()
    lab.router_base(lab=other)
    bridge = lab.client("can_bridge", lab.arm_tcp)
    heartbeat = Inbox(bridge, "manus/heartbeat")
    sequencer = lab.open("services/sequencer.json5", other, connect=(lab.base_tcp,))
    end = time.monotonic() + 1.5
    while time.monotonic() < end:
        sequencer.put("manus/heartbeat", b"alive")
        time.sleep(0.1)
    assert list(arm.info.routers_zid()) == []
    assert heartbeat.items == []


def test_lab_files_missing_are_named(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"root_ca_certificate = .*ca.pem.*manus certs"):
        build_config(
            settings_from_env(
                {}, config_file=str(ZENOH_DIR / "router-arm.json5"), lab_dir=str(tmp_path)
            )
        )
    empty = tmp_path / "empty.usrpwd"
    empty.write_text("controller:\n")
    with pytest.raises(ConfigError, match=r"empty.usrpwd:1: expected 'user:password'"):
        build_config(
            settings_from_env(
                {},
                config_file=str(ZENOH_DIR / "services/controller.json5"),
                credentials_file=str(empty),
            )
        )


def test_manus_certs_writes_the_lab_with_extra_arm_names(tmp_path: Path) -> None:
    from cryptography import x509

    from manus_stack.cli import main

    out = tmp_path / "lab"
    assert main(["certs", "--out", str(out), "--days", "2", "--arm-name", "arm.lab.test"]) == 0
    cert = x509.load_pem_x509_certificate((out / "router-arm.pem").read_bytes())
    names = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert "arm.lab.test" in names.get_values_for_type(x509.DNSName)
    assert cert.subject.get_attributes_for_oid(x509.NameOID.COMMON_NAME)[0].value == "router-arm"
    users = (out / "users-arm.txt").read_text().splitlines()
    assert (out / "controller.usrpwd").read_text().strip() in users
    assert (out / "ca.key").stat().st_mode & 0o077 == 0, "private key readable by others"


def test_no_impostors_through_the_tls_link_as_deployed(lab: Lab) -> None:
    """A rogue client on the base computer (a real identity: the supervisor's, then the
    recorder's) cannot publish another service's keys, answer another service's
    queryable, or hold another service's liveliness token; the owners still can. The
    policy is the one generated from the endpoint table (manus_stack/policy.py)."""
    arm = lab.router_arm()
    lab.router_base()
    assert _until(lambda: len(list(arm.info.routers_zid())) == 1), "no TLS link"
    bridge = lab.client("can_bridge", lab.arm_tcp)
    controller = lab.client("controller", lab.arm_tcp)
    sequencer = lab.client("sequencer", lab.base_tcp)
    for name in ("supervisor", "recorder"):
        rogue = lab.client(name, lab.base_tcp)
        # Publish: fake joint states (the bridge's) and heartbeats (the sequencer's).
        joints = Inbox(controller, "manus/state/joints")
        beats = Inbox(controller, "manus/heartbeat")
        for _ in range(5):
            rogue.put("manus/state/joints", b"fake joints")
            rogue.put("manus/heartbeat", b"fake beat")
            time.sleep(0.05)
        assert _put_until_received(bridge, joints, "manus/state/joints", b"real joints")
        assert _put_until_received(sequencer, beats, "manus/heartbeat", b"real beat")
        time.sleep(QUIET_S)
        assert b"fake joints" not in joints.items and b"fake beat" not in beats.items, name
        # Declare: answer the planner's queryable; hold the controller's token.
        fake_plan = _answering(rogue, "manus/planner/plan")
        token = rogue.liveliness().declare_token("manus/alive/controller")
        time.sleep(QUIET_S)
        assert _replies(sequencer, "manus/planner/plan", 0.5) == [], name
        tokens = sequencer.liveliness().get("manus/alive/**", timeout=0.5)
        assert [str(r.ok.key_expr) for r in tokens if r.ok is not None] == [], name
        token.undeclare()
        fake_plan.undeclare()
    # The owners can: the planner answers its queryable, the controller holds its token.
    planner = lab.client("planner", lab.base_tcp)
    real_plan = _answering(planner, "manus/planner/plan")
    assert _until(lambda: bool(_replies(sequencer, "manus/planner/plan", 0.3)))
    assert _replies(sequencer, "manus/planner/plan") == [b"accepted manus/planner/plan"]
    token = controller.liveliness().declare_token("manus/alive/controller")

    def alive() -> list[str]:
        replies = sequencer.liveliness().get("manus/alive/**", timeout=0.5)
        return [str(r.ok.key_expr) for r in replies if r.ok is not None]

    assert _until(lambda: alive() == ["manus/alive/controller"])
    token.undeclare()
    real_plan.undeclare()


def test_the_deployed_policy_is_generated_from_the_endpoint_table() -> None:
    from manus_stack.policy import main

    assert main(["--check"]) == 0, "run: manus schemas --update"
