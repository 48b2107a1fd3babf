"""Scene files: the default wheelchair scene, and malformed files refused with file, line
and field (PyYAML node marks), before anything is built from them."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from manus.collision import CollisionModel
from manus.config import DEFAULT_ARM, FOLDED_Q_DEG, UNFOLDED_Q_DEG
from manus.scene import (
    CLASSES,
    SHIPPED_SOURCE,
    SceneError,
    default_scene,
    default_scene_path,
    load_scene,
    parse_scene,
    scene_from_setting,
)

GOOD = """\
version: 1
mount:
  xyz_mm: [350, -420, 1000]
objects:
  - name: head
    class: person
    shape: sphere
    radius_mm: 110
    xyz_mm: [-20, 0, 1230]
  - name: table
    class: environment
    shape: box
    size_mm: [600, 1000, 40]
    xyz_mm: [1100, 0, 720]
zones:
  - {name: workspace, kind: keep_in, shape: box,
     size_mm: [1700, 1400, 1700], xyz_mm: [350, -200, 950]}
"""


def write(tmp_path: Path, text: str) -> Path:
    file = tmp_path / "scene.yaml"
    file.write_text(text)
    return file


def test_default_scene_has_the_user_the_chair_and_the_room() -> None:
    scene = default_scene()
    names = {o.name: o.cls for o in scene.objects}
    assert names["head"] == "person" and names["armrest_right"] == "chair"
    assert names["table"] == "environment"
    assert {o.cls for o in scene.objects} == set(CLASSES)
    assert [z.kind for z in scene.zones].count("keep_in") == 1
    assert scene.clearance == pytest.approx(
        {"person": 0.05, "chair": 0.015, "environment": 0.015, "self": 0.01}
    )
    # named the same in every clone, so recordings replay wherever the code lives
    assert scene.source == SHIPPED_SOURCE == "manus/data/wheelchair.yaml"
    assert load_scene(default_scene_path()).source == SHIPPED_SOURCE
    assert scene_from_setting("default") is not None and scene_from_setting("none") is None


def test_default_scene_leaves_the_fold_poses_clear() -> None:
    model = CollisionModel(default_scene(), DEFAULT_ARM)
    for q_deg in (FOLDED_Q_DEG, UNFOLDED_Q_DEG):
        assert model.clearance(np.radians(q_deg)).margin > 0.0


def test_mount_places_the_arm_in_the_chair_frame(tmp_path: Path) -> None:
    scene = load_scene(write(tmp_path, GOOD))
    assert scene.mount[:3, 3] == pytest.approx([0.35, -0.42, 1.0])
    head = scene.objects[0]
    # The head, 0.37 m behind, 0.42 m left of and 0.23 m above the shoulder.
    assert scene.in_base(head.body.pose)[:3, 3] == pytest.approx([-0.37, 0.42, 0.23])


@pytest.mark.parametrize(
    ("old", "new", "line", "field", "problem"),
    [
        ("shape: sphere", "shape: cone", 7, "objects[0].shape", "unknown value 'cone'"),
        ("radius_mm: 110", "radius_mm: -5", 8, "objects[0].radius_mm", "must be > 0, got -5"),
        (
            "size_mm: [600, 1000, 40]",
            "size_mm: [600, .nan, 40]",
            13,
            "objects[1].size_mm[1]",
            "must be a finite number",
        ),
        ("    xyz_mm: [-20, 0, 1230]\n", "", 5, "objects[0].xyz_mm", "missing field"),
        ("    class: person\n", "", 5, "objects[0].class", "missing field"),
        (
            "class: environment",
            "class: furniture",
            11,
            "objects[1].class",
            "unknown value 'furniture' (allowed: person, chair, environment)",
        ),
        (
            "radius_mm: 110",
            "radius_mm: 110\n    colour: red",
            9,
            "objects[0].colour",
            "unknown field",
        ),
        (
            "radius_mm: 110",
            "size_mm: [1, 2, 3]",
            8,
            "objects[0].size_mm",
            "not a field of a sphere",
        ),
        ("kind: keep_in", "kind: keep_near", 16, "zones[0].kind", "unknown value 'keep_near'"),
        (
            "  xyz_mm: [350, -420, 1000]",
            "  xyz_mm: [350, -420]",
            3,
            "mount.xyz_mm",
            "must be a list of 3 numbers",
        ),
        ("name: table", "name: head", 10, "objects[1].name", "name 'head' already used on line 5"),
    ],
)
def test_malformed_scene_names_file_line_and_field(
    tmp_path: Path, old: str, new: str, line: int, field: str, problem: str
) -> None:
    assert old in GOOD
    file = write(tmp_path, GOOD.replace(old, new, 1))
    with pytest.raises(SceneError) as err:
        load_scene(file)
    message = str(err.value)
    assert message.startswith(f"{file}:{line}: {field}: "), message
    assert problem in message
    assert "\n" not in message


def test_object_overlapping_the_arms_base_is_refused(tmp_path: Path) -> None:
    # A box around the column under the shoulder (the mount is at (350, -420, 1000) mm).
    text = GOOD.replace(
        "zones:",
        "  - {name: bag, class: environment, shape: box, size_mm: [200, 200, 200],"
        " xyz_mm: [350, -420, 800]}\nzones:",
    )
    file = write(tmp_path, text)
    scene = load_scene(file)  # the file itself is well formed
    with pytest.raises(SceneError) as err:
        CollisionModel(scene, DEFAULT_ARM)
    assert str(err.value).startswith(f"{file}:15: objects.bag: overlaps the arm's column")


def test_yaml_syntax_error_names_the_line(tmp_path: Path) -> None:
    file = write(tmp_path, GOOD.replace("radius_mm: 110", "radius_mm: [110"))
    with pytest.raises(SceneError, match=rf"^{file}:\d+: not valid YAML"):
        load_scene(file)


def test_other_problems_name_the_file() -> None:
    with pytest.raises(SceneError, match=r"^<scene>: the scene file is empty"):
        parse_scene("")
    with pytest.raises(SceneError, match=r"^nowhere\.yaml: cannot read the scene file"):
        load_scene("nowhere.yaml")
    with pytest.raises(
        SceneError, match=r"^<scene>:1: version: the file format: this stack reads format 1, got 2"
    ):
        parse_scene(GOOD.replace("version: 1", "version: 2"))
    with pytest.raises(SceneError, match=r"^<scene>:18: zones\[1\]\.kind: a second keep_in"):
        parse_scene(
            GOOD + "  - {name: second, kind: keep_in, shape: sphere, radius_mm: 9,"
            " xyz_mm: [0, 0, 0]}\n"
        )


def test_plane_normal_is_normalised() -> None:
    text = GOOD.replace(
        "zones:",
        "  - {name: wall, class: environment, shape: plane, normal: [0, 3, 0],"
        " xyz_mm: [0, -900, 0]}\nzones:",
    )
    wall = parse_scene(text).objects[-1]
    assert wall.body.size == pytest.approx((0.0, 1.0, 0.0))
    assert math.isclose(wall.body.pose[1, 3], -0.9)


def test_a_malformed_scene_stops_the_services_before_anything_moves(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from manus_stack.cli import main
    from services.controller.config import ControllerConfig
    from services.controller.core import ControllerCore
    from services.planner.config import PlannerConfig
    from services.planner.core import PlannerCore
    from services.sequencer.config import SequencerConfig
    from services.sequencer.core import SequencerCore
    from services.simulator.config import SimConfig
    from services.simulator.core import SimCore

    bad = write(tmp_path, GOOD.replace("radius_mm: 110", "radius_mm: .nan"))
    expected = f"{bad}:8: objects[0].radius_mm: must be a finite number, got .nan"
    for build in (
        lambda: PlannerCore(PlannerConfig(scene=str(bad))),
        lambda: ControllerCore(ControllerConfig(scene=str(bad))),
        lambda: SequencerCore(SequencerConfig(scene=str(bad))),
        lambda: SimCore(SimConfig(scene=str(bad))),
    ):
        with pytest.raises(SceneError) as err:
            build()
        assert str(err.value) == expected
    root = Path(__file__).resolve().parent.parent
    assert main(["plan", str(root / "paths" / "thesis_circle.txt"), "--scene", str(bad)]) == 1
    assert capsys.readouterr().err == f"manus plan: error: {expected}\n"
