"""The Foxglove layout of the viewer: 3D view, plots and the log.

Built with the SDK's ``foxglove.layouts``; the repository ships its output as
``services/viewer/manus.layout.json`` (a test keeps the two equal; ``manus view --layout
FILE`` writes it again). Import it in the app (Layouts, Import from file) after opening
the connection ``ws://127.0.0.1:8765`` or a file written by ``manus export --json``.

Left: the 3D panel in ``base_link`` with the URDF read from the robot description topic
(the arm moves with ``viz/tf``), the planned and executed paths, the via poses, the
scene and protection zones (``viz/scene``), the objects (``viz/objects``: held ones move
with the gripper), a follow goal's target, standoff and predicted target (``viz/follow``)
and the true path (hidden; tick it). Right:
joint tracking errors, commanded increments (the 20-speed counts), the gripper path
error, bridge health, and the log (arm warnings, phases, goals, task events).
"""

from __future__ import annotations

from pathlib import Path

import foxglove.layouts as fl

LAYOUT_FILE = Path(__file__).with_name("manus.layout.json")


def _series(topic: str, field: str, label: str) -> fl.PlotSeries:
    """A plot series; the topic is quoted (our topics have no leading slash)."""
    return fl.PlotSeries(
        value=f'"{topic}".{field}', label=label, enabled=True, timestamp_method="receiveTime"
    )


def build_layout(prefix: str = "manus") -> fl.Layout:
    """The layout for an arm whose keys start with ``prefix``."""
    viz = f"{prefix}/viz"
    three_d = fl.ThreeDeePanel(
        title="arm",
        config=fl.ThreeDeeConfig(
            follow_tf="base_link",
            layers={
                "grid": fl.BaseRendererGridLayerSettings(),
                "manus-urdf": fl.BaseRendererUrdfLayerSettings(
                    label="Manus",
                    source_type="topic",
                    topic=f"{viz}/robot_description",
                    display_mode="visual",
                    control_mode="transforms",
                ),
            },
            topics={
                f"{viz}/planned": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                f"{viz}/executed": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                f"{viz}/true": fl.BaseRendererSceneUpdateTopicSettings(visible=False),
                f"{viz}/via_poses": fl.BaseRendererPosesTopicSettings(visible=True),
                f"{viz}/scene": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                f"{viz}/objects": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                f"{viz}/follow": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
            },
        ),
    )
    fb = f"{prefix}/controller/feedback"
    errors = fl.PlotPanel(
        title="joint errors [rad] (reference - actual)",
        config=fl.PlotConfig(
            paths=[_series(fb, f"error[{i}]", f"q{i + 1}") for i in range(6)], show_legend=True
        ),
    )
    cmd = f"{prefix}/cmd/joint_velocity"
    counts = fl.PlotPanel(
        title="commanded increments (counts)",
        config=fl.PlotConfig(
            paths=[_series(cmd, f"counts[{i}]", f"c{i}") for i in range(8)], show_legend=True
        ),
    )
    gripper_error = fl.PlotPanel(
        title="gripper position error [m]; bridge reply latency [ms]",
        config=fl.PlotConfig(
            paths=[
                _series(fb, "position_error", "path error [m]"),
                _series(f"{prefix}/state/bridge", "reply_latency_ms", "reply latency [ms]"),
                _series(f"{prefix}/state/bridge", "missed_windows", "missed windows"),
            ],
            show_legend=True,
        ),
    )
    logs = fl.LogPanel(title="events", config=fl.LogConfig(topic_to_render=f"{viz}/log"))
    right = fl.SplitContainer(
        direction="column",
        items=[
            fl.SplitItem(content=errors),
            fl.SplitItem(content=counts),
            fl.SplitItem(content=gripper_error),
            fl.SplitItem(content=logs),
        ],
    )
    return fl.Layout(
        content=fl.SplitContainer(
            direction="row",
            items=[
                fl.SplitItem(proportion=3, content=three_d),
                fl.SplitItem(proportion=2, content=right),
            ],
        )
    )


def layout_json(prefix: str = "manus") -> str:
    """The layout as the JSON text the app imports."""
    return build_layout(prefix).to_json() + "\n"
