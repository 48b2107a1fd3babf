"""A picture of the arm in its scene: objects by class, protection zones, the arm's
collision bodies at any joint angles, and the tightest clearance (``manus scene show``).

Drawn in the chair frame with matplotlib's Agg backend: boxes, spheres, cylinders and
capsules as wire surfaces, a plane as a wire square around its point; objects coloured by
class, keep-out zones red, the keep-in workspace green, the arm blue and the body of the
tightest clearance magenta; a legend says which is which. The heading names the file,
its file format and the scene version (:func:`scene_heading`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from manus.collision import CollisionModel
from manus.config import ArmConfig
from manus.scene import FILE_FORMAT, Primitive, Scene
from manus.urdf import Shape

COLOURS = {"person": "tab:orange", "chair": "dimgray", "environment": "saddlebrown"}
"""Object colour by class."""

KEEP_OUT, KEEP_IN, ARM, TIGHTEST = "red", "green", "tab:blue", "magenta"
"""Colours of keep-out zones, the keep-in workspace, the arm and its tightest body."""


class ScenePicture(NamedTuple):
    """What :func:`draw_scene` drew.

    Attributes:
        clearance: the tightest clearance in words (the title's second line).
        heading: the scene's name, file format and scene version (its first line).
        legend: the legend's labels, in order.
    """

    clearance: str
    heading: str
    legend: list[str]


def scene_heading(scene: Scene) -> str:
    """``wheelchair.yaml (file format 1), scene version 0``: the file format is what the
    file's ``version:`` key says; the scene version counts a running stack's updates (0:
    as read from the file)."""
    return f"{Path(scene.source).name} (file format {FILE_FORMAT}), scene version {scene.version}"


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
) -> ScenePicture:
    """Draw ``scene`` with the arm at DH angles ``q`` [rad] and gripper ``opening`` [m]
    to ``png``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    model = CollisionModel(scene, arm, opening=opening)
    found = model.clearance(np.asarray(q, dtype=float))
    fig = plt.figure(figsize=(9, 8))
    ax = fig.add_subplot(projection="3d")
    legend: list[tuple[str, str, float]] = []  # label, colour, line width
    for cls, colour in COLOURS.items():
        if any(obj.cls == cls for obj in scene.objects):
            legend.append((f"{cls} (needs {scene.clearance[cls] * 1e3:.0f} mm)", colour, 1.0))
    for obj in scene.objects:
        _draw(ax, obj.body, color=COLOURS[obj.cls], linewidth=0.4)
    for kind, colour, label in (("keep_out", KEEP_OUT, "keep-out zone"),
                                ("keep_in", KEEP_IN, "keep-in workspace")):  # fmt: skip
        zones = [z for z in scene.zones if z.kind == kind]
        for zone in zones:
            _draw(ax, zone.body, color=colour, linewidth=0.6 if kind == "keep_in" else 0.4)
        if zones:
            legend.append((label, colour, 1.0))
    for i, shape in enumerate(model.shapes):
        colour = TIGHTEST if shape.name == found.check.body else ARM
        _draw(ax, _arm_primitive(shape, model, i, scene.mount), color=colour, linewidth=0.8)
    legend.append((f"arm (self: needs {scene.clearance['self'] * 1e3:.0f} mm)", ARM, 2.0))
    if found.check.body:
        legend.append((f"{found.check.body}: tightest clearance", TIGHTEST, 2.0))
    handles = [Line2D([], [], color=c, linewidth=w, label=label) for label, c, w in legend]
    ax.legend(handles=handles, loc="upper left", fontsize=8)
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
    heading = scene_heading(scene)
    ax.set_title(f"{heading}\n{title}", fontsize=9)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return ScenePicture(title, heading, [label for label, _, _ in legend])
