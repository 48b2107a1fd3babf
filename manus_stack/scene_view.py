"""A picture of the arm in its scene: objects by class, protection zones, the arm's
collision bodies at any joint angles, and the tightest clearance (``manus scene show``).

Drawn in the chair frame with matplotlib's Agg backend: boxes, spheres, cylinders and
capsules as wire surfaces, a plane as a square patch around its point, keep-out zones
red, the keep-in workspace as green edges, the arm blue (the body of the tightest
clearance red) with a line between the two nearest points.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from manus.collision import CollisionModel
from manus.config import ArmConfig
from manus.scene import Primitive, Scene
from manus.urdf import Shape

COLOURS = {"person": "tab:orange", "chair": "dimgray", "environment": "saddlebrown"}


def _surfaces(shape: str, size: tuple[float, ...]) -> Iterator[np.ndarray]:
    """Wire surfaces (3, u, v) of a primitive in its own frame."""
    u = np.linspace(0.0, 2.0 * math.pi, 17)
    if shape == "box":
        hx, hy, hz = (s / 2.0 for s in size)
        for axis in range(3):
            for sign in (-1.0, 1.0):
                a, b = np.meshgrid(np.linspace(-1, 1, 2), np.linspace(-1, 1, 2))
                face = [a, b]
                face.insert(axis, np.full_like(a, sign))
                yield np.array(face) * np.array([hx, hy, hz])[:, None, None]
    elif shape == "sphere":
        v = np.linspace(0.0, math.pi, 9)
        r = size[0]
        yield r * np.array(
            [
                np.outer(np.cos(u), np.sin(v)),
                np.outer(np.sin(u), np.sin(v)),
                np.outer(0 * u + 1, np.cos(v)),
            ]
        )
    else:  # cylinder, capsule (z axis); a capsule's caps drawn as hemispheres
        r, length = size
        z = np.linspace(-length / 2.0, length / 2.0, 2)
        yield np.array(
            [
                r * np.outer(np.cos(u), 0 * z + 1),
                r * np.outer(np.sin(u), 0 * z + 1),
                np.outer(0 * u + 1, z),
            ]
        )
        if shape == "capsule":
            for sign in (-1.0, 1.0):
                v = np.linspace(0.0, math.pi / 2.0, 5)
                yield np.array(
                    [
                        r * np.outer(np.cos(u), np.cos(v)),
                        r * np.outer(np.sin(u), np.cos(v)),
                        sign * (length / 2.0 + r * np.outer(0 * u + 1, np.sin(v))),
                    ]
                )


def _placed(surface: np.ndarray, pose: np.ndarray) -> np.ndarray:
    flat = surface.reshape(3, -1)
    return np.asarray((pose[:3, :3] @ flat + pose[:3, 3:4]).reshape(surface.shape))


def _draw(ax: Any, body: Primitive, **style: Any) -> None:
    if body.shape == "plane":
        n = np.asarray(body.size)
        e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        a, b = np.meshgrid(np.linspace(-0.8, 0.8, 5), np.linspace(-0.8, 0.8, 5))
        p = body.pose[:3, 3]
        pts = p[:, None, None] + e1[:, None, None] * a + e2[:, None, None] * b
        ax.plot_wireframe(*pts, color=style.get("color", "gray"), linewidth=0.3)
        return
    for surface in _surfaces(body.shape, body.size):
        ax.plot_wireframe(*_placed(surface, body.pose), **style)


def _arm_primitive(shape: Shape, model: CollisionModel, index: int, mount: np.ndarray) -> Primitive:
    M = model.geom_data.oMg[index]
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = M.rotation, M.translation
    size = tuple(shape.size)
    if shape.name == "gripper":
        size = (model.opening + 0.03, *size[1:])
    return Primitive("box" if shape.kind == "box" else shape.kind, size, mount @ pose)


def draw_scene(
    scene: Scene, q: np.ndarray, png: str | Path, *, arm: ArmConfig, opening: float = 0.0
) -> str:
    """Draw ``scene`` with the arm at DH angles ``q`` [rad]; returns the tightest
    clearance in words (also the plot's title)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    model = CollisionModel(scene, arm, opening=opening)
    found = model.clearance(np.asarray(q, dtype=float))
    fig = plt.figure(figsize=(9, 8))
    ax = fig.add_subplot(projection="3d")
    for obj in scene.objects:
        _draw(ax, obj.body, color=COLOURS[obj.cls], linewidth=0.4)
    for zone in scene.zones:
        colour = "green" if zone.kind == "keep_in" else "red"
        _draw(ax, zone.body, color=colour, linewidth=0.6 if zone.kind == "keep_in" else 0.4)
    for i, shape in enumerate(model.shapes):
        colour = "red" if shape.name == found.check.body else "tab:blue"
        _draw(ax, _arm_primitive(shape, model, i, scene.mount), color=colour, linewidth=0.8)
    ax.set_xlabel("x forward [m]")
    ax.set_ylabel("y left [m]")
    ax.set_zlabel("z up [m]")
    ax.set_xlim(-0.6, 1.4)
    ax.set_ylim(-1.0, 1.0)
    ax.set_zlim(0.0, 2.0)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    ax.view_init(elev=20, azim=-60)
    words = ", ".join(f"{math.degrees(v):.0f}" for v in q)
    title = f"q = ({words}) deg: {found.describe()}"
    ax.set_title(f"{Path(scene.source).name} version {scene.version}\n{title}", fontsize=9)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return title
