"""The informed set of a search for a shorter path (Informed RRT*'s idea, for restarts).

A path from ``start`` through ``q`` to a goal state ``g`` is at least ``|q - start| +
|g - q|`` long (joint space, Euclidean), so a path shorter than ``length`` lies wholly in
the union over the goal states of the prolate spheroids ``|q - start| + |g - q| <
length``; goal states farther than ``length`` from the start cannot end one. A search
for a shorter path samples only the spheroids' bounding box and calls every
configuration outside them invalid.
"""

from __future__ import annotations

import math

import numpy as np


class Informed:
    """The configurations that can lie on a path shorter than ``length``.

    Args:
        start: the start [rad], shape (6,).
        goals: the goal states [rad], shape (k, 6).
        length: the length to beat [rad].
    """

    def __init__(self, start: np.ndarray, goals: np.ndarray, length: float) -> None:
        self.start = np.asarray(start, dtype=float)
        self.length = length
        near = np.linalg.norm(goals - self.start, axis=1) < length
        self.goals = np.asarray(goals[near])
        """The goal states a shorter path can end at, shape (m, 6) (m may be 0)."""

    def box(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The spheroids' bounding box within ``lo`` .. ``hi`` [rad], each shape (6,)."""
        lows, highs = [], []
        a = self.length / 2.0  # semi-major axis
        for g in self.goals:
            d = g - self.start
            c = float(np.linalg.norm(d)) / 2.0
            b = math.sqrt(max(a * a - c * c, 0.0))  # semi-minor axes
            u = d / (2.0 * c) if c > 0.0 else np.zeros_like(d)
            half = np.sqrt(a * a * u * u + b * b * (1.0 - u * u))  # extent per joint
            mid = (self.start + g) / 2.0
            lows.append(mid - half)
            highs.append(mid + half)
        return np.maximum(lo, np.min(lows, axis=0)), np.minimum(hi, np.max(highs, axis=0))

    def contains(self, q: np.ndarray) -> bool:
        """Whether a path through ``q`` [rad] can be shorter than the length."""
        ahead = float(np.linalg.norm(self.goals - q, axis=1).min())
        return float(np.linalg.norm(q - self.start)) + ahead < self.length
