"""The surfaces objects rest on: the horizontal tops of the scene's objects, and the floor.

A surface is the top face of an upright box or of a cylinder standing on end (any class:
a cup can stand on the table, the seat or a lap), or a plane whose normal points up.
The floor of the chair frame (z = 0, docs/scene.md) is always one, named ``floor``,
whether or not the scene has a plane there. :meth:`Supports.below` finds the highest
surface under a point; a released object falls onto it.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from manus.scene import Scene

FLOOR = "floor"
"""The name of the floor surface (z = 0 of the chair frame)."""

_LEVEL = math.cos(math.radians(1.0))
"""A face counts as horizontal when its normal is within 1 deg of vertical."""


class Surface(NamedTuple):
    """A horizontal surface an object can rest on.

    Attributes:
        name: the scene object it is the top of (``floor``: the floor).
        cls: its class (``person``, ``chair``, ``environment``).
        top: its height in the chair frame [m].
        centre: the centre of its footprint (x, y) [m], shape (2,).
        axes: the footprint's axes (rows: unit x and y) [-], shape (2, 2).
        half: the footprint's half sizes [m], shape (2,) (a disc: (radius, inf); the
            floor or a plane: (inf, inf)).
    """

    name: str
    cls: str
    top: float
    centre: np.ndarray
    axes: np.ndarray
    half: np.ndarray

    def holds(self, x: float, y: float) -> bool:
        """Whether the point (x, y) [m] lies over this surface."""
        d = np.array([x, y]) - self.centre
        if math.isinf(self.half[1]) and not math.isinf(self.half[0]):
            return bool(math.hypot(*d) <= self.half[0])  # a disc
        local = self.axes @ d
        return bool(np.all(np.abs(local) <= self.half))


def _surface(
    name: str, cls: str, shape: str, size: tuple[float, ...], pose: np.ndarray
) -> Surface | None:
    R, c = pose[:3, :3], pose[:3, 3]
    up = abs(float(R[2, 2]))
    everywhere = np.array([math.inf, math.inf])
    if shape == "plane":
        if size[2] >= _LEVEL:
            return Surface(name, cls, float(c[2]), np.zeros(2), np.eye(2), everywhere)
        return None
    if up < _LEVEL or shape not in ("box", "cylinder"):
        return None
    if shape == "cylinder":
        top = float(c[2]) + size[1] / 2.0
        return Surface(name, cls, top, c[:2].copy(), np.eye(2), np.array([size[0], math.inf]))
    # An upright box (its own z vertical): the footprint turns with its yaw.
    axes = R[:2, :2].T
    axes = axes / np.linalg.norm(axes, axis=1, keepdims=True)
    return Surface(
        name, cls, float(c[2]) + size[2] / 2.0, c[:2].copy(), axes, np.array(size[:2]) / 2.0
    )


class Supports:
    """The surfaces of a scene, in the chair frame.

    Args:
        scene: the scene (None: the floor alone).
    """

    def __init__(self, scene: Scene | None) -> None:
        found: list[Surface] = []
        for obj in scene.objects if scene is not None else ():
            surface = _surface(obj.name, obj.cls, obj.body.shape, obj.body.size, obj.body.pose)
            if surface is not None:
                found.append(surface)
        if not any(math.isinf(s.half[0]) and s.top == 0.0 for s in found):
            found.append(
                Surface(FLOOR, "environment", 0.0, np.zeros(2), np.eye(2), np.full(2, math.inf))
            )
        self.surfaces = sorted(found, key=lambda s: -s.top)
        """Highest first."""

    def below(self, x: float, y: float, z: float) -> Surface:
        """The highest surface under (x, y) whose top is at most ``z`` [m] (the floor when
        nothing else is, or when ``z`` is below the floor)."""
        for surface in self.surfaces:
            if surface.top <= z and surface.holds(x, y):
                return surface
        return self.floor

    @property
    def floor(self) -> Surface:
        """The lowest surface that spans everywhere."""
        found: Surface = next(s for s in reversed(self.surfaces) if math.isinf(s.half[0]))
        return found

    def named(self, name: str) -> Surface:
        """The surface called ``name``.

        Raises:
            KeyError: none is.
        """
        for surface in self.surfaces:
            if surface.name == name:
                return surface
        raise KeyError(name)
