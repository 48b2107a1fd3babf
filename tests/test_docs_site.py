"""The documentation site (mkdocs.yml, docs/): every page is in the navigation, and the
site builds with warnings as errors (broken links, links to missing headings, pages left
out of the navigation), as .ci/run builds it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"


def nav_pages(entries: list[Any]) -> list[str]:
    """Every page of a MkDocs ``nav`` (nested sections flattened), in order."""
    out: list[str] = []
    for entry in entries:
        value = next(iter(entry.values())) if isinstance(entry, dict) else entry
        if isinstance(value, list):
            out += nav_pages(value)
        else:
            out.append(str(value))
    return out


def test_every_page_is_in_the_nav_once_and_every_nav_entry_is_a_page() -> None:
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    pages = nav_pages(config["nav"])
    assert len(pages) == len(set(pages)), f"pages listed twice: {pages}"
    on_disk = sorted(p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md"))
    assert sorted(pages) == on_disk, "add each docs/*.md page to the nav of mkdocs.yml"
    assert pages[0] == "index.md"


def test_the_site_builds_strict(tmp_path: Path) -> None:
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    run = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-d", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "site" / "commands" / "index.html").is_file()
    assert (tmp_path / "site" / "img" / "scene.png").is_file()
