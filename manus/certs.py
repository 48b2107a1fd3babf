"""Lab credentials for the two-computer deployment: a CA, router certificates, passwords.

``manus certs --out DIR`` writes everything the Zenoh files of ``deploy/zenoh/`` name
under ``/etc/manus/lab`` (compose.yaml mounts ``DIR`` there):

    ca.pem                     lab certificate authority (both routers trust only it)
    ca.key                     its private key (keep it off the robot; mode 0600)
    router-arm.pem, .key       TLS server certificate of the arm computer's router
                               (common name ``router-arm``, names manus-arm, localhost, 127.0.0.1)
    router-base.pem, .key      TLS client certificate of the base computer's router
                               (common name ``router-base``; mTLS: the arm router checks it)
    users-arm.txt              ``user:password`` lines the arm router accepts (usrpwd)
    users-base.txt             the same for the base router
    <user>.usrpwd              one Zenoh user's ``user:password`` line (a service's
                               MANUS_ZENOH_CREDENTIALS; its own file only)

Passwords are 32 random URL-safe characters (``secrets``), certificates are ECDSA P-256,
valid for ``days`` (default 365). Nothing here is a secret worth committing: generate a
fresh set per lab; the repository holds only the Zenoh files that name these paths.
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import secrets
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from manus.errors import ConfigError

ARM_USERS = ("controller", "can_bridge", "guardian", "simulator", "router-base")
"""Zenoh users of the arm computer's router (``router-base``: the base router's link)."""

BASE_USERS = ("planner", "sequencer", "recorder", "supervisor", "panel")
"""Zenoh users of the base computer's router (``panel``: ``manus panel``, docs/panel.md)."""

ROUTER_NAMES: Mapping[str, tuple[str, ...]] = {
    "router-arm": ("manus-arm", "localhost", "127.0.0.1"),
    "router-base": ("manus-base", "localhost", "127.0.0.1"),
}
"""Router certificate common names and their subject alternative names."""


@dataclass(frozen=True)
class Identity:
    """A key pair and its certificate (PEM bytes)."""

    key_pem: bytes
    cert_pem: bytes


def _name(common_name: str) -> x509.Name:
    return x509.Name(
        [
            x509.NameAttribute(NameOID.ORGANIZATION_NAME, "Manus lab"),
            x509.NameAttribute(NameOID.COMMON_NAME, common_name),
        ]
    )


def _key_pem(key: ec.EllipticCurvePrivateKey) -> bytes:
    return key.private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )


def make_ca(common_name: str = "Manus lab CA", days: int = 365) -> Identity:
    """A self-signed certificate authority valid from now for ``days`` [days]."""
    key = ec.generate_private_key(ec.SECP256R1())
    now = dt.datetime.now(dt.UTC)
    cert = (
        x509.CertificateBuilder()
        .subject_name(_name(common_name))
        .issuer_name(_name(common_name))
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=days))
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=True,
                crl_sign=True,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .sign(key, hashes.SHA256())
    )
    return Identity(_key_pem(key), cert.public_bytes(serialization.Encoding.PEM))


def issue(ca: Identity, common_name: str, names: Iterable[str], days: int = 365) -> Identity:
    """A certificate for ``common_name`` signed by ``ca``, usable as TLS server and client.

    Args:
        ca: the issuing authority (from :func:`make_ca`).
        common_name: the subject's common name (what Zenoh ACL ``cert_common_names`` match).
        names: subject alternative names: DNS names or IP addresses.
        days: validity from now [days].
    """
    ca_key = serialization.load_pem_private_key(ca.key_pem, password=None)
    ca_cert = x509.load_pem_x509_certificate(ca.cert_pem)
    if not isinstance(ca_key, ec.EllipticCurvePrivateKey):
        raise ConfigError("CA key: expected an EC private key")
    key = ec.generate_private_key(ec.SECP256R1())
    alt: list[x509.GeneralName] = []
    for name in names:
        try:
            alt.append(x509.IPAddress(ipaddress.ip_address(name)))
        except ValueError:
            alt.append(x509.DNSName(name))
    now = dt.datetime.now(dt.UTC)
    builder = (
        x509.CertificateBuilder()
        .subject_name(_name(common_name))
        .issuer_name(ca_cert.subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=days))
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(
            x509.ExtendedKeyUsage(
                [ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]
            ),
            critical=False,
        )
        .add_extension(
            x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()),
            critical=False,
        )
    )
    if alt:
        builder = builder.add_extension(x509.SubjectAlternativeName(alt), critical=False)
    cert = builder.sign(ca_key, hashes.SHA256())
    return Identity(_key_pem(key), cert.public_bytes(serialization.Encoding.PEM))


def _write(path: Path, data: bytes, secret: bool) -> None:
    path.write_bytes(data)
    path.chmod(0o600 if secret else 0o644)


def write_lab(
    out: Path, days: int = 365, ca: Identity | None = None, arm_names: Iterable[str] = ()
) -> list[Path]:
    """Write a fresh lab set into ``out`` (created if missing); the paths written.

    Args:
        out: target directory (existing files of the same names are replaced).
        days: certificate validity [days].
        ca: sign with this authority instead of a new one (e.g. to add a computer).
        arm_names: more names (host names, IP addresses) of the arm computer for its
            router's certificate, when the base router reaches it by another name than
            manus-arm (the base verifies the name it connects to).
    """
    if not 1 <= days <= 3650:
        raise ConfigError(f"certificate validity {days} days outside 1..3650")
    out.mkdir(parents=True, exist_ok=True)
    ca = ca or make_ca(days=days)
    written: list[Path] = []

    def put(name: str, data: bytes, secret: bool) -> None:
        _write(out / name, data, secret)
        written.append(out / name)

    put("ca.pem", ca.cert_pem, secret=False)
    put("ca.key", ca.key_pem, secret=True)
    for router, names in ROUTER_NAMES.items():
        extra = tuple(arm_names) if router == "router-arm" else ()
        ident = issue(ca, router, (*names, *extra), days=days)
        put(f"{router}.pem", ident.cert_pem, secret=False)
        put(f"{router}.key", ident.key_pem, secret=True)
    for table, users in (("users-arm.txt", ARM_USERS), ("users-base.txt", BASE_USERS)):
        lines = []
        for user in users:
            password = secrets.token_urlsafe(24)
            lines.append(f"{user}:{password}\n")
            put(f"{user}.usrpwd", lines[-1].encode(), secret=True)
        put(table, "".join(lines).encode(), secret=True)
    return written
