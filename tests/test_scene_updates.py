"""Scenes replaced at run time (``planner/scene``): validated whole, versioned, and the
version travels with every plan checked against it."""

from __future__ import annotations

import math
from pathlib import Path as FilePath

from manus.config import UNFOLDED_Q_DEG
from manus.node import Node, QueryError
from manus.scene import default_scene_path
from manus.session import ZenohSettings
from manus.viapoints import load_path
from schemas import endpoints as ep
from schemas.collision import SceneReply, SceneState, SceneUpdate
from schemas.planning import PlanReply, PlanRequest, ViaPointPath
from schemas.state import JointState
from services.planner.core import PlannerCore
from services.planner.shell import PlannerShell
from tests.conftest import eventually

ROOT = FilePath(__file__).resolve().parent.parent
UNFOLDED = [math.radians(q) for q in UNFOLDED_Q_DEG]
SQUARE = PlanRequest(
    ViaPointPath(path=load_path(ROOT / "paths" / "thesis_square.txt")), start=UNFOLDED
)
DEFAULT = default_scene_path().read_text()
# A cup on a tray right where the square passes (the gripper's start, in the chair frame).
CUP = DEFAULT.replace(
    "  # The room.\n",
    "  # The room.\n"
    "  - {name: cup, class: environment, shape: cylinder, radius_mm: 40, length_mm: 100,"
    " xyz_mm: [560, -170, 1200]}\n",
)


def test_an_added_object_refuses_the_next_plan_and_versions_count_up() -> None:
    core = PlannerCore()
    first = core.plan(SQUARE)
    assert first.trajectory is not None and first.trajectory.scene_version == 0
    reply = core.update_scene(SceneUpdate(text=CUP, source="cup.yaml"))
    assert reply == SceneReply(accepted=True, version=1, error="")
    refused = core.plan(SQUARE)
    assert refused.error is not None and refused.error.reason == "collision"
    assert "from cup (environment: needs 15 mm)" in refused.error.message
    assert "(scene version 1: cup.yaml)" in refused.error.message
    # The cup taken away again: version 2, the square plans.
    assert core.update_scene(SceneUpdate(text=DEFAULT, source="default", base_version=1)) == (
        SceneReply(accepted=True, version=2, error="")
    )
    again = core.plan(SQUARE)
    assert again.trajectory is not None and again.trajectory.scene_version == 2


def test_a_bad_update_is_refused_whole_and_changes_nothing() -> None:
    core = PlannerCore()
    bad = CUP.replace("radius_mm: 40", "radius_mm: -40")
    reply = core.update_scene(SceneUpdate(text=bad, source="cup.yaml"))
    assert not reply.accepted and reply.version == 0
    assert reply.error.startswith("cup.yaml:")
    assert "objects[14].radius_mm: must be > 0, got -40" in reply.error
    stale = core.update_scene(SceneUpdate(text=CUP, source="cup.yaml", base_version=3))
    assert not stale.accepted and "scene version 0 is in use" in stale.error
    plan = core.plan(SQUARE)
    assert plan.trajectory is not None and plan.trajectory.scene_version == 0


def test_scene_updates_over_the_bus(zenoh_settings: ZenohSettings) -> None:
    with (
        PlannerShell(zenoh_settings) as shell,
        Node("supervisor", zenoh_settings, liveliness=False) as client,
    ):
        assert client.keys(ep.SCENE) == "test/planner/scene"

        def answers() -> bool:
            try:
                client.query(client.keys(ep.PLAN), SQUARE, PlanReply, timeout=1.0)
            except QueryError:
                return False
            return True

        eventually(answers)
        states: list[SceneState] = []
        client.subscribe(client.keys(ep.SCENE_STATE), SceneState, lambda m, t: states.append(m))
        reply = client.query(client.keys(ep.SCENE), SceneUpdate(text=CUP, source="cup"), SceneReply)
        assert reply.accepted and reply.version == 1
        plan = client.query(client.keys(ep.PLAN), SQUARE, PlanReply)
        assert plan.error is not None and "scene version 1" in plan.error.message
        assert shell.core.collision is not None

        def published() -> bool:  # the subscription may take a moment to reach the router
            if states:
                return True
            client.query(client.keys(ep.SCENE), SceneUpdate(text=CUP, source="cup"), SceneReply)
            return False

        eventually(published)
        assert states[0].source == "cup" and states[0].version >= 1
        assert shell.core.scene_state is not None
        assert 1 <= states[-1].version <= shell.core.scene_state.version


def test_an_accepted_update_is_published_and_the_guard_and_folds_follow_it() -> None:
    from manus.config import DEFAULT_ARM
    from services.controller.core import ControllerCore
    from services.planner.wiring import WIRING
    from services.sequencer.core import SequencerCore
    from services.sequencer.validate import scene_fold_checker

    planner = PlannerCore()
    reply, published = WIRING.answer(ep.SCENE.suffix).handle(
        planner, SceneUpdate(text=CUP, source="cup.yaml"), 0
    )
    assert reply.accepted
    ((endpoint, state),) = published
    assert endpoint == ep.SCENE_STATE and isinstance(state, SceneState)
    assert (state.version, state.source, state.text) == (1, "cup.yaml", CUP)
    refused, nothing = WIRING.answer(ep.SCENE.suffix).handle(
        planner, SceneUpdate(text="version: 1\n"), 0
    )
    assert not refused.accepted and nothing == []

    controller = ControllerCore()
    assert controller.guard is not None
    assert controller.on_scene(state) == []
    model = controller.guard.guard.model
    assert model.scene is not None and model.scene.version == 1
    assert any(c.other == "cup" for c in model.checks)
    # A scene that does not build leaves the guard as it was.
    controller.on_scene(SceneState(version=2, text="nonsense: [", source="bad"))
    assert controller.guard.guard.model is model

    assert scene_fold_checker(state, DEFAULT_ARM) is not None
    assert scene_fold_checker(SceneState(version=2, text="x: 1\n"), DEFAULT_ARM) is None
    sequencer = SequencerCore()
    before = sequencer.fold_check
    assert sequencer.on_scene(state) == [] and sequencer.fold_check is not before


def _js(stamp_ms: float) -> JointState:
    return JointState(stamp_ns=round(stamp_ms * 1e6), seq=round(stamp_ms / 60), position=UNFOLDED,
                      gripper=0.0, valid=True, mode="joint", encoder=[0] * 7,
                      applied_velocity=[0.0] * 6, applied_gripper_velocity=0.0,
                      applied_kind="none", applied_seq=-1)  # fmt: skip


def test_the_scene_in_use_is_announced_at_the_first_joint_state_then_every_second() -> None:
    from services.planner.config import PlannerConfig
    from services.planner.wiring import WIRING

    planner = PlannerCore()
    out = [WIRING.feed(planner, ep.JOINTS, _js(60.0 * k), 0) for k in range(40)]
    announced = [k for k, o in enumerate(out) if o]
    assert announced == [0, 17, 34]  # stamps 0, 1020, 2040 ms: every >= 1000 ms
    ((endpoint, state),) = out[0]
    assert endpoint == ep.SCENE_STATE and state == planner.scene_state
    assert (state.version, state.text) == (0, DEFAULT)
    planner.update_scene(SceneUpdate(text=CUP, source="cup.yaml"))
    later = [o for k in range(40, 58) if (o := WIRING.feed(planner, ep.JOINTS, _js(60.0 * k), 0))]
    assert [(m.version, m.source) for ((_, m),) in later if isinstance(m, SceneState)] == [
        (1, "cup.yaml")
    ]
    # A restarted bridge (stamps from 0 again) gets the scene at once.
    assert WIRING.feed(planner, ep.JOINTS, _js(0.0), 0)
    quiet = PlannerCore(PlannerConfig(scene_every_ms=0.0))
    assert not any(WIRING.feed(quiet, ep.JOINTS, _js(60.0 * k), 0) for k in range(40))
    assert not any(
        WIRING.feed(PlannerCore(PlannerConfig(scene="none")), ep.JOINTS, _js(60.0 * k), 0)
        for k in range(40)
    )


def test_a_controller_and_sequencer_started_after_an_update_learn_it_from_the_announcement() -> (
    None
):
    from services.controller.core import ControllerCore
    from services.planner.wiring import WIRING
    from services.sequencer.core import SequencerCore

    # the scene they read at start announced: nothing to rebuild
    fresh = ControllerCore()
    assert fresh.guard is not None
    before = fresh.guard.guard.model
    ((_, start),) = WIRING.feed(PlannerCore(), ep.JOINTS, _js(0.0), 0)
    assert isinstance(start, SceneState)
    fresh.on_scene(start)
    assert fresh.guard.guard.model is before
    planner = PlannerCore()
    planner.update_scene(SceneUpdate(text=CUP, source="cup.yaml"))
    # started (or restarted) now: they read the shipped scene, without the cup
    controller, sequencer = ControllerCore(), SequencerCore()
    assert controller.guard is not None
    assert not any(c.other == "cup" for c in controller.guard.guard.model.checks)
    ((_, state),) = WIRING.feed(planner, ep.JOINTS, _js(0.0), 0)
    assert isinstance(state, SceneState)
    controller.on_scene(state)
    sequencer.on_scene(state)
    model = controller.guard.guard.model
    assert model.scene is not None and model.scene.version == 1
    assert any(c.other == "cup" for c in model.checks)
    fold_check = sequencer.fold_check
    # the same scene announced again changes nothing (no rebuild every second)
    ((_, again),) = WIRING.feed(planner, ep.JOINTS, _js(1020.0), 0)
    assert isinstance(again, SceneState) and again == state
    controller.on_scene(again)
    sequencer.on_scene(again)
    assert controller.guard.guard.model is model and sequencer.fold_check is fold_check


def test_the_example_supervisor_replaces_the_scene(
    zenoh_settings: ZenohSettings, router_endpoint: str, tmp_path: FilePath
) -> None:
    import subprocess
    import sys

    bad = tmp_path / "bad.yaml"
    bad.write_text(CUP.replace("radius_mm: 40", "radius_mm: -40"))
    with PlannerShell(zenoh_settings) as shell:
        proc = subprocess.run(
            [sys.executable, str(ROOT / "examples" / "supervisor.py"), "--connect",
             router_endpoint, "--prefix", "test", "--scene", str(bad), "paths/x.txt"],
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
        assert proc.returncode == 2, proc.stdout + proc.stderr
        assert f"scene refused: {bad}:" in proc.stdout
        assert "radius_mm: must be > 0, got -40" in proc.stdout
        assert shell.core.scene_state is not None  # nothing changed: the scene read at start
        assert shell.core.scene_state.version == 0
