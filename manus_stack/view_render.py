"""A still of what the viewer shows, drawn with matplotlib (the Foxglove app itself cannot be
loaded offline here, so this is a rendering of the same data, not a screenshot of the app).

The recording goes through the viewer's core (:class:`services.viewer.core.ViewerCore`)
up to ``at_s``; the arm is drawn from the same link transforms the core publishes on
``viz/tf`` (each link's origin, joined in chain order, and the fingers), with the planned
path and via points of ``viz/planned``, the executed path of ``viz/executed`` and the
scene's solids of ``viz/scene`` (:func:`services.viewer.surroundings.solids` of the scene
the core draws at that time), as wireframes in their colours (planes left out: they are
unbounded).

    python -m manus_stack.view_render tests/data/thesis_square.mcap -o view.png --at 12
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from manus.config import ArmConfig, load_arm_config
from manus.urdf import GRIPPER_FRAME
from services.recorder.reading import Recording
from services.viewer.config import ViewerConfig
from services.viewer.core import ViewerCore
from services.viewer.model import LINK_NAMES, ROOT_FRAME, link_transforms
from services.viewer.surroundings import Solid, solids

_RING = np.linspace(0.0, 2 * np.pi, 25)


def _wireframe(solid: Solid) -> list[np.ndarray]:
    """Polylines (k, 3) in base_link outlining a cube, sphere or cylinder [m]."""
    hx, hy, hz = (v / 2 for v in solid.size)
    if solid.shape == "cube":
        c = np.array([[x, y, z] for x in (-hx, hx) for y in (-hy, hy) for z in (-hz, hz)])
        edges = [(0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5),
                 (2, 6), (3, 7)]  # fmt: skip
        local = [c[[a, b]] for a, b in edges]
    else:
        circle = np.c_[hx * np.cos(_RING), hy * np.sin(_RING), 0 * _RING]
        if solid.shape == "sphere":
            local = [circle, circle[:, [0, 2, 1]], circle[:, [2, 0, 1]]]
        else:
            local = [circle + np.array([0, 0, -hz]), circle + np.array([0, 0, hz])]
            local += [np.array([[x, y, -hz], [x, y, hz]]) for x, y in circle[::6, :2]]
    R, t = solid.pose[:3, :3], solid.pose[:3, 3]
    return [pts @ R.T + t for pts in local]


def _frames(q: list[float], gripper: float, arm: ArmConfig) -> dict[str, np.ndarray]:
    """Every frame's origin in base_link from the link transforms [m]."""
    world = {ROOT_FRAME: np.eye(4)}
    for tf in link_transforms(q, gripper, arm):
        x, y, z, w = tf.rotation
        R = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, tf.translation
        world[tf.child] = world[tf.parent] @ T
    return world


def _draw_scene(ax: Any, core: ViewerCore) -> list[np.ndarray]:
    """Wireframes of the scene's solids (planes left out); their points [m]."""
    points = [np.zeros((0, 3))]
    for drawn in solids(core.scene) if core.scene is not None else []:
        for solid in drawn.solids:
            if solid.size[2] < 0.01:  # a plane's square: unbounded, left out
                continue
            r, g, b, a = solid.rgba
            for line in _wireframe(solid):
                ax.plot(*line.T, color=(r, g, b, min(1.0, 0.35 + a)), lw=0.8)
                points.append(line)
    return points


def render(path: str, png: str, at_s: float | None = None) -> ViewerCore:
    """Draw the view of ``path`` at ``at_s`` seconds (None: the end) into ``png``."""
    rec = Recording(path)
    core = ViewerCore(ViewerConfig(prefix=rec.info.prefix or "manus", arm=load_arm_config()))
    until = None if at_s is None else rec.info.start_ns + round(at_s * 1e9)
    for m in rec.messages():
        if until is not None and m.log_ns > until:
            break
        core.on_sample(m.key, m.payload, m.log_ns)
    js = core.joints
    if js is None:
        raise SystemExit(f"{path}: no valid joint state before {at_s} s")
    world = _frames(list(js.position), js.gripper, core.config.arm)
    fig = plt.figure(figsize=(8, 7))
    ax = fig.add_subplot(projection="3d")
    chain = [ROOT_FRAME, *LINK_NAMES, GRIPPER_FRAME]
    # the links' visuals follow each DH offset: d along the link's z, then a along its x
    pts = [world[ROOT_FRAME][:3, 3] - np.array([0, 0, 0.35])]
    for name in chain:
        pts.append(world[name][:3, 3])
    P = np.array(pts)
    ax.plot(P[:, 0], P[:, 1], P[:, 2], "-", color="0.55", lw=7, solid_capstyle="round")
    ax.scatter(P[1:-1, 0], P[1:-1, 1], P[1:-1, 2], color="#3373cc", s=60, depthshade=False)
    for finger in ("finger_left", "finger_right"):
        T = world[finger]
        tip, base = T[:3, 3], T[:3, 3] - 0.07 * T[:3, 2]
        ax.plot(*zip(base, tip, strict=True), color="#f28c1a", lw=4)
    planned, via = core.planned
    if planned:
        A = np.array(planned)
        ax.plot(A[:, 0], A[:, 1], A[:, 2], color="#3399ff", lw=1.5, label="planned (preview)")
        V = np.array(via)
        ax.scatter(V[:, 0], V[:, 1], V[:, 2], color="#3399ff", s=18, label="via points")
    executed = core.executed
    if len(executed) >= 2:
        E = np.array(executed)
        ax.plot(E[:, 0], E[:, 1], E[:, 2], color="#ff7319", lw=2.2, label="executed")
    scene_points = _draw_scene(ax, core)
    everything = np.vstack(
        [P, *scene_points, *(np.array(x) for x in (planned, executed) if len(x) >= 2)]
    )
    centre = (everything.max(0) + everything.min(0)) / 2
    half = (everything.max(0) - everything.min(0)).max() / 2 + 0.05
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.view_init(elev=18, azim=-25)
    t = (js.stamp_ns - rec.info.start_ns) / 1e9
    ax.set_title(
        f"{path.rsplit('/', 1)[-1]} at {t:.2f} s: the viewer's base_link frame\n"
        "(matplotlib rendering of the data manus view sends, scene as wireframes; "
        "not the Foxglove app)"
    )
    ax.legend(loc="upper left")
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return core


def main(argv: list[str] | None = None) -> int:
    """``python -m manus_stack.view_render FILE -o PNG [--at S]``."""
    parser = argparse.ArgumentParser(prog="python -m manus_stack.view_render")
    parser.add_argument("file")
    parser.add_argument("-o", "--output", required=True)
    parser.add_argument("--at", type=float, help="seconds from the start (default: the end)")
    args = parser.parse_args(argv)
    render(args.file, args.output, args.at)
    print(f"view: {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
