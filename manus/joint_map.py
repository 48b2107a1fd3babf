"""Encoder (motor) angles <-> DH joint angles: the one place the map lives.

The map is docs/protocol.md, Encoder map.

The arm reports motor angles e1..e6; joints 2 and 3 are mechanically coupled and joint 4
has a 90 deg offset. In degrees:

    q1 = e1   q2 = -e2   q3 = e3 - e2 + 90   q4 = e4 + 90   q5 = e5   q6 = e6

and for increments (commands): de1 = dq1, de2 = -dq2, de3 = dq3 - dq2, de4..6 = dq4..6.
Every function here is linear, works in any consistent angle unit for increments, and
on arrays of shape (..., 6).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

_OFFSET_Q3 = math.pi / 2
_OFFSET_Q4 = math.pi / 2

# dq = M @ de  and  de = M_INV @ dq  (increments, no offsets)
M_ENCODER_TO_DH = np.array(
    [
        [1, 0, 0, 0, 0, 0],
        [0, -1, 0, 0, 0, 0],
        [0, -1, 1, 0, 0, 0],
        [0, 0, 0, 1, 0, 0],
        [0, 0, 0, 0, 1, 0],
        [0, 0, 0, 0, 0, 1],
    ],
    dtype=float,
)
# The coupling matrix is an involution (M @ M = I): the same matrix maps both ways.
M_DH_TO_ENCODER = M_ENCODER_TO_DH.copy()
_OFFSET = np.array([0.0, 0.0, _OFFSET_Q3, _OFFSET_Q4, 0.0, 0.0])


def encoder_to_dh(e: np.ndarray) -> np.ndarray:
    """DH joint angles [rad] from encoder angles [rad], shape (..., 6)."""
    e = np.asarray(e, dtype=float)
    return np.asarray(e @ M_ENCODER_TO_DH.T + _OFFSET)


def dh_to_encoder(q: np.ndarray) -> np.ndarray:
    """Encoder angles [rad] from DH joint angles [rad], shape (..., 6)."""
    q = np.asarray(q, dtype=float)
    return np.asarray((q - _OFFSET) @ M_DH_TO_ENCODER.T)


def dh_increments_to_encoder(dq: np.ndarray) -> np.ndarray:
    """Motor increments (or rates) from DH increments (or rates), shape (..., 6)."""
    return np.asarray(np.asarray(dq, dtype=float) @ M_DH_TO_ENCODER.T)


def encoder_increments_to_dh(de: np.ndarray) -> np.ndarray:
    """DH increments (or rates) from motor increments (or rates), shape (..., 6)."""
    return np.asarray(np.asarray(de, dtype=float) @ M_ENCODER_TO_DH.T)


# Scalar twins for the controller's cycle, where NumPy's per-call overhead on six values
# costs more than the arithmetic (tests keep them equal to the matrix forms above).


def dh_to_encoder_list(q: Sequence[float]) -> list[float]:
    """Encoder angles [rad] from six DH joint angles [rad], as plain floats."""
    q1, q2, q3, q4, q5, q6 = q
    return [q1 + 0.0, 0.0 - q2, (q3 - _OFFSET_Q3) - q2, q4 - _OFFSET_Q4, q5 + 0.0, q6 + 0.0]


def encoder_increments_to_dh_list(de: Sequence[float]) -> list[float]:
    """DH increments (or rates) from six motor increments (or rates), as plain floats."""
    e1, e2, e3, e4, e5, e6 = de
    return [e1 + 0.0, 0.0 - e2, e3 - e2, e4 + 0.0, e5 + 0.0, e6 + 0.0]


def dh_increments_to_encoder_list(dq: Sequence[float]) -> list[float]:
    """Motor increments (or rates) from six DH increments (or rates), as plain floats."""
    d1, d2, d3, d4, d5, d6 = dq
    return [d1 + 0.0, 0.0 - d2, d3 - d2, d4 + 0.0, d5 + 0.0, d6 + 0.0]
