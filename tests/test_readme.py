"""The README is a front page: its two commands are the ones CI runs and the site's home
page shows, it stays short, and what it links to exists."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
MOST_LINES = 200
"""The front page's length: the rest belongs to the documentation site (docs/)."""


def commands(text: str) -> list[str]:
    """The set-up commands of a page (``python3 -m venv ...`` lines)."""
    return re.findall(r"^(python3 -m venv .*)$", text, flags=re.MULTILINE)


def test_ci_runs_the_readme_test_command() -> None:
    test_command = next(c for c in commands(README.read_text()) if "pytest" in c)
    assert test_command in (ROOT / ".ci" / "run").read_text().splitlines()


def test_the_readme_has_the_demo_command() -> None:
    assert commands(README.read_text()) == [
        "python3 -m venv .venv && .venv/bin/pip install -q -e . && .venv/bin/manus demo",
        "python3 -m venv .venv && .venv/bin/pip install -q -e '.[test]' && "
        ".venv/bin/python -m pytest -q",
    ]


def test_the_site_home_page_shows_the_same_two_commands() -> None:
    assert commands((ROOT / "docs" / "index.md").read_text()) == commands(README.read_text())


def test_the_readme_is_a_front_page() -> None:
    lines = README.read_text().splitlines()
    assert len(lines) <= MOST_LINES, f"README.md has {len(lines)} lines (at most {MOST_LINES})"


def test_what_the_readme_links_to_exists() -> None:
    targets = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", README.read_text())
    local = [t for t in targets if not re.match(r"[a-z]+:", t)]
    assert "docs/img/scene.png" in local and "docs/commands.md" in local
    missing = [t for t in local if not (ROOT / t).exists()]
    assert not missing, f"README.md links to files that do not exist: {missing}"


def test_ci_builds_the_docs_site_strict() -> None:
    ci = (ROOT / ".ci" / "run").read_text()
    assert re.search(r"^[^#\n]*\bmkdocs build --strict\b", ci, flags=re.MULTILINE)
