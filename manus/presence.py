"""Who is on the bus: the liveliness tokens of the services, read once.

Every service's :class:`manus.node.Node` holds ``<prefix>/alive/<service>`` (it runs) and
``<prefix>/where/<service>/<host>/<pid>`` (on which computer and process); a service
that is off on purpose in a deployment is announced by ``<prefix>/disabled/<service>/<why>``
(the CAN guardian beside a bridge whose channel admits one reader:
``disabled/guardian/single_reader_channel``, docs/deployment.md, CAN interfaces). These
functions ask the bus which tokens are up now (``manus status``, ``manus up``, the
supervisor's tools); :class:`~manus.node.Node` offers the first two as methods.
"""

from __future__ import annotations

import zenoh

from schemas.endpoints import ALIVE, DISABLED, WHERE
from schemas.keys import Keys


def token_keys(session: zenoh.Session, key: str, timeout: float) -> list[str]:
    """The keys of the liveliness tokens matching ``key`` that are up now, as full keys."""
    replies = session.liveliness().get(key, timeout=timeout)
    return [str(r.ok.key_expr) for r in replies if r.ok is not None]


def alive_services(session: zenoh.Session, keys: Keys, timeout: float = 1.0) -> set[str]:
    """Names of the services whose ``alive`` tokens are up now."""
    found = token_keys(session, keys.alive_all, timeout)
    return {keys.suffix(k).removeprefix(f"{ALIVE}/") for k in found}


def service_hosts(
    session: zenoh.Session, keys: Keys, timeout: float = 1.0
) -> dict[str, list[tuple[str, int]]]:
    """Service name -> [(host name, pid), ...] of every node alive now (``where``)."""
    found: dict[str, list[tuple[str, int]]] = {}
    for key in token_keys(session, keys.where_all, timeout):
        parts = keys.suffix(key).split("/")
        if len(parts) == 4 and parts[0] == WHERE and parts[3].isdigit():
            found.setdefault(parts[1], []).append((parts[2], int(parts[3])))
    return found


def disabled_services(session: zenoh.Session, keys: Keys, timeout: float = 1.0) -> dict[str, str]:
    """Service name -> why it is off on purpose, of every ``disabled`` token up now."""
    found: dict[str, str] = {}
    for key in token_keys(session, keys.disabled_all, timeout):
        parts = keys.suffix(key).split("/", 2)
        if len(parts) == 3 and parts[0] == DISABLED and parts[1]:
            found[parts[1]] = parts[2]
    return found
