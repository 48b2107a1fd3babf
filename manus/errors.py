"""The exception family of the Manus stack.

Every error the stack raises on purpose derives from :class:`ManusError`, one subclass
per domain, so that callers can catch a whole domain and tests can assert the type.
Messages name what was wrong (file, line, via point, joint, value) and the limit.
"""

from __future__ import annotations


class ManusError(Exception):
    """Base of every deliberate error in the Manus stack."""


class ConfigError(ManusError, ValueError):
    """A configuration value is missing, malformed or out of its allowed range."""


class KinematicsError(ManusError):
    """A pose cannot be reached: out of the workspace, singular, or beyond a joint limit.

    Attributes:
        reason: short machine-readable reason: ``"unreachable"``, ``"singular"``,
            ``"joint_limit"`` or ``"branch"``.
        joint: 1-based joint number concerned, when one is.
        value: the offending value (rad for joints), when there is one.
        limit: the limit it broke, when there is one.
    """

    def __init__(
        self,
        message: str,
        *,
        reason: str,
        joint: int | None = None,
        value: float | None = None,
        limit: float | None = None,
    ) -> None:
        super().__init__(message)
        self.reason = reason
        self.joint = joint
        self.value = value
        self.limit = limit


class ProtocolError(ManusError, ValueError):
    """A CAN frame does not follow the Manus transparent-mode protocol."""


class SchemaError(ManusError, ValueError):
    """A bus payload does not decode to the message type it claims to be."""
