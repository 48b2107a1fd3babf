"""The panel's task buttons: which tasks the person can start, from a directory of task files.

A task directory holds ``panel.toml`` (the buttons, in the order they show) and the task
files they name (TOML task files, docs/sequencer.md: ``manus run FILE`` runs each of them
too). The panel ships one (``manus_stack/panel/tasks/``); ``manus panel --tasks DIR``
uses another. ``panel.toml``::

    [[button]]
    id = "fetch"                  # letters, digits, '_' and '-'
    label = "Fetch"               # the button's words
    task = "fetch.toml"           # the task file, relative to panel.toml
    objects = ["cup", "bottle"]   # optional: the button asks which; "{object}" in the
                                  # task file's text is replaced by the choice
    about = "the {object}"        # optional: what the task is about, for messages
                                  # ("The cup is out of reach.")
    say = { folded = "..." }      # optional: this button's own sentence for a trouble
                                  # (manus_stack.panel.words.Trouble) instead of the usual

A button whose task file does not exist is shown as not set up (pressing it says so):
adding the task is adding its file. A task file that exists is parsed when the panel
starts (with each object substituted), so a broken one stops ``manus panel`` with every
problem and its line, before anyone presses a button.
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

from manus.errors import ConfigError
from manus_stack.panel.words import Trouble, sentence
from schemas.sequencing import Task
from services.sequencer.taskfile import TaskFileError, parse_task_text

DEFAULT_DIR = Path(__file__).resolve().parent / "tasks"
"""The task directory shipped with the panel."""
CONFIG = "panel.toml"
"""The file of a task directory that lists the buttons."""
OBJECT = "{object}"
"""The placeholder a task file's text holds for the chosen object."""

_NAME = re.compile(r"^[A-Za-z0-9_-]{1,40}$")
_KEYS = ("id", "label", "task", "objects", "about", "say")


@dataclass(frozen=True)
class TaskButton:
    """One task button.

    Attributes:
        id: its name (page element ``task-<id>``).
        label: its words.
        file: the task file.
        objects: the choices it asks for (empty: none).
        about: what the task is about, for messages (``{object}`` replaced).
        say: this button's own sentences for some troubles.
    """

    id: str
    label: str
    file: Path
    objects: tuple[str, ...] = ()
    about: str = ""
    say: tuple[tuple[Trouble, str], ...] = ()

    @property
    def ready(self) -> bool:
        """Its task file exists."""
        return self.file.is_file()

    def about_words(self, choice: str = "") -> str:
        """What the task is about, with ``choice`` for the object ("the cup")."""
        return self.about.replace(OBJECT, choice)

    def sentence(self, trouble: Trouble, choice: str = "") -> str:
        """What to tell the user about ``trouble`` met by this button's task."""
        own = dict(self.say).get(trouble)
        return own if own is not None else sentence(trouble, self.about_words(choice))

    def task(self, choice: str = "") -> Task:
        """The task to submit, with ``choice`` in place of ``{object}``.

        Raises:
            ConfigError: ``choice`` is not one of :attr:`objects` (or given to a button
                without objects), or the task file is missing.
            TaskFileError: the task file has problems (each with its line).
        """
        if self.objects and choice not in self.objects:
            raise ConfigError(
                f"button {self.id!r}: object {choice!r} is not one of {list(self.objects)}"
            )
        if not self.objects and choice:
            raise ConfigError(f"button {self.id!r} takes no object (got {choice!r})")
        if not self.ready:
            raise ConfigError(f"button {self.id!r}: task file {self.file} does not exist")
        text = self.file.read_text(encoding="utf-8").replace(OBJECT, choice)
        source = f"{self.file}" + (f" ({choice})" if choice else "")
        return parse_task_text(text, source=source, base=self.file.parent)


def load_buttons(directory: Path = DEFAULT_DIR) -> list[TaskButton]:
    """The buttons of the task directory ``directory`` (its ``panel.toml``), checked.

    Raises:
        ConfigError: ``panel.toml`` is missing, not TOML, or a button is malformed (the
            file, the button's number and the key named), or a task file that exists
            does not parse (every problem with its line).
    """
    config = directory / CONFIG
    try:
        data = tomllib.loads(config.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(f"{config}: cannot read the panel's buttons: {exc}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{config}: not valid TOML: {exc}") from exc
    raw = data.get("button")
    if not isinstance(raw, list) or not raw or set(data) - {"button"}:
        raise ConfigError(f"{config}: write one [[button]] table per button, nothing else")
    buttons = [_button(config, i, entry) for i, entry in enumerate(raw, start=1)]
    ids = [b.id for b in buttons]
    twice = sorted({i for i in ids if ids.count(i) > 1})
    if twice:
        raise ConfigError(f"{config}: button id(s) used twice: {', '.join(twice)}")
    problems: list[str] = []
    for button in buttons:
        if not button.ready:
            continue
        for choice in button.objects or ("",):
            try:
                button.task(choice)
            except TaskFileError as exc:
                problems += exc.errors
    if problems:
        raise ConfigError(f"{config}: task file problems:\n  " + "\n  ".join(problems))
    return buttons


def _button(config: Path, number: int, entry: object) -> TaskButton:
    where = f"{config}: button {number}"
    if not isinstance(entry, dict):
        raise ConfigError(f"{where}: a [[button]] table expected")
    unknown = sorted(set(entry) - set(_KEYS))
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {unknown} (allowed: {', '.join(_KEYS)})")
    for key in ("id", "label", "task"):
        if not isinstance(entry.get(key), str) or not entry[key]:
            raise ConfigError(f"{where}: {key!r} must be a non-empty string")
    if not _NAME.match(entry["id"]):
        raise ConfigError(f"{where}: id {entry['id']!r}: letters, digits, '_' and '-' only")
    objects = entry.get("objects", [])
    if not isinstance(objects, list) or not all(
        isinstance(o, str) and _NAME.match(o) for o in objects
    ):
        raise ConfigError(
            f"{where}: objects must be a list of names (letters, digits, '_', '-'), got {objects!r}"
        )
    about = entry.get("about", "")
    if not isinstance(about, str):
        raise ConfigError(f"{where}: about must be a string, got {about!r}")
    say = entry.get("say", {})
    kinds = [t.value for t in Trouble]
    if not isinstance(say, dict) or not all(
        k in kinds and isinstance(v, str) and v for k, v in say.items()
    ):
        raise ConfigError(
            f"{where}: say must map troubles ({', '.join(kinds)}) to sentences, got {say!r}"
        )
    return TaskButton(
        id=entry["id"],
        label=entry["label"],
        file=config.parent / entry["task"],
        objects=tuple(objects),
        about=about,
        say=tuple((Trouble(k), v) for k, v in say.items()),
    )
