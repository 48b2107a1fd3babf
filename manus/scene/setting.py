"""Which scene a service uses: its ``scene`` setting (``""``, ``default``, ``none`` or
a file) and ``$MANUS_SCENE``, and the scene state it announces before any run-time update.
"""

from __future__ import annotations

import os
from pathlib import Path

from manus.scene.file import default_scene_path, load_scene, source_name
from manus.scene.model import Scene, SceneError
from schemas.collision import SceneState

SCENE_ENV = "MANUS_SCENE"
"""Environment variable naming the scene every service uses when its setting is empty."""


def scene_path(setting: str) -> Path | None:
    """The file a service's ``scene`` setting names: ``""`` -> ``$MANUS_SCENE`` if set,
    else the shipped one; ``default`` -> the shipped one; ``none`` -> None (no scene: no
    collision checks); else the setting is the file's path. Every service's setting
    defaults to ``""``, so one environment variable gives the planner, sequencer,
    controller and simulator the same scene."""
    if setting == "":
        setting = os.environ.get(SCENE_ENV, "") or "default"
    if setting == "default":
        return default_scene_path()
    if setting == "none":
        return None
    return Path(setting)


def scene_from_setting(setting: str) -> Scene | None:
    """The scene of :func:`scene_path` (None: none)."""
    path = scene_path(setting)
    return None if path is None else load_scene(path)


def start_scene_state(setting: str) -> SceneState | None:
    """The scene of a service's ``scene`` setting as the planner announces it before any
    run-time update (scene version 0, the file's text, its name); None: no scene.

    Raises:
        SceneError: the file cannot be read.
    """
    path = scene_path(setting)
    if path is None:
        return None
    try:
        return SceneState(version=0, text=path.read_text(), source=source_name(path))
    except OSError as exc:
        raise SceneError(f"{path}: cannot read the scene file: {exc.strerror}") from exc
