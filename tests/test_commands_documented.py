"""`manus --help` and the documentation list the same commands: every subcommand (and every
second-level one: ``kin fk``, ``scene check``, ``task pause``, ...) is in the README's
command table and on docs/commands.md, and neither documents a command that does not
exist. The benchmarks page lists every bench."""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
from pathlib import Path

from manus_stack.bench import BENCHES
from manus_stack.cli import build_parser

ROOT = Path(__file__).resolve().parent.parent


def help_commands() -> list[str]:
    """The subcommands ``manus --help`` lists, in its order."""
    run = subprocess.run(
        [sys.executable, "-m", "manus_stack.cli", "--help"],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    section = run.stdout.split("COMMAND\n", 2)[-1]
    return re.findall(r"^    (\w[\w-]*)\s", section, flags=re.MULTILINE)


def second_level(command: str) -> set[str]:
    """The subcommands or the one action of ``manus COMMAND`` (``kin``: fk, ik, ...;
    ``task``: pause, resume, ...; none: empty). Lists of names (``manus bench [NAME...]``)
    are not actions: the benchmarks page lists those."""
    parser = build_parser(command)
    top = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for action in top.choices[command]._actions:
        if isinstance(action, argparse._SubParsersAction):
            return set(action.choices)
        if not action.option_strings and action.choices is not None and action.nargs is None:
            return {str(c) for c in action.choices}
    return set()


def table_commands(page: Path) -> list[list[str]]:
    """The commands in the first column of a page's tables, each split into words (a
    ``a\\|b`` alternative stays one word)."""
    rows = re.findall(r"^\| `(manus [^`]*)` \|", page.read_text(), flags=re.MULTILINE)
    return [row.replace("\\|", "|").split()[1:] for row in rows]


def test_help_lists_the_commands() -> None:
    assert {"kin", "demo", "up", "scene", "plot"} <= set(help_commands())


def test_the_readme_table_has_every_command_and_no_other() -> None:
    documented = [words[0] for words in table_commands(ROOT / "README.md")]
    assert len(documented) == len(set(documented)), "a command listed twice in README.md"
    assert sorted(documented) == sorted(help_commands())


def test_the_command_page_has_every_command_and_subcommand_and_no_other() -> None:
    rows = table_commands(ROOT / "docs" / "commands.md")
    commands = help_commands()
    assert {words[0] for words in rows} == set(commands)
    for command in commands:
        expected = second_level(command)
        if not expected:
            continue
        documented: set[str] = set()
        for words in rows:
            if words[0] == command and len(words) > 1 and re.fullmatch(r"[a-z|_-]+", words[1]):
                documented.update(words[1].split("|"))
        assert documented == expected, f"manus {command}: documented {documented}"


def test_the_benchmarks_page_lists_every_bench() -> None:
    page = (ROOT / "docs" / "benchmarks.md").read_text()
    documented = re.findall(r"^\| `(\w+)` \|", page, flags=re.MULTILINE)
    assert sorted(documented) == sorted(BENCHES)
