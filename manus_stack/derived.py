"""The repository's files derived from the endpoint table, kept current by one command.

``manus schemas --update`` rewrites them and ``manus schemas --check`` fails when one is
not current (a test runs the check):

- ``schemas/supervisor.schema.json``: the supervisor's API (:mod:`schemas.export`);
- ``docs/architecture.md``: the key table, between its ``BEGIN``/``END`` comment lines
  (:func:`schemas.endpoints.markdown_table`);
- ``deploy/zenoh/router-arm.json5`` and ``router-base.json5``: the access control
  (:mod:`manus_stack.policy`).

Files that are not there (an installed package without the repository) are skipped.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from manus_stack import policy
from schemas.endpoints import TABLE, markdown_table
from schemas.export import SUPERVISOR_FILE, dumps, supervisor_document

ROOT = Path(__file__).resolve().parent.parent
TABLE_BEGIN = (
    "<!-- BEGIN key table: generated from schemas/endpoints.py by `manus schemas --update` -->"
)
TABLE_END = "<!-- END key table -->"


def _between(text: str, begin: str, end: str, body: str, where: Path) -> str:
    head, sep, rest = text.partition(begin)
    _, sep2, tail = rest.partition(end)
    if not sep or not sep2:
        raise ValueError(f"{where}: no {begin!r} ... {end!r} lines")
    return f"{head}{begin}\n{body}{end}{tail}"


def derived() -> list[tuple[Path, Callable[[str], str]]]:
    """(file, its current text -> what it should be) for every derived file."""
    architecture = ROOT / "docs" / "architecture.md"
    keys = markdown_table(TABLE)
    files: list[tuple[Path, Callable[[str], str]]] = [
        (SUPERVISOR_FILE, lambda _: dumps(supervisor_document())),
        (
            architecture,
            lambda text: _between(text, TABLE_BEGIN, TABLE_END, keys, architecture),
        ),
    ]
    for router in policy.COMPUTERS:
        files.append((policy.ZENOH_DIR / f"router-{router}.json5", _router(router)))
    return files


def _router(router: str) -> Callable[[str], str]:
    return lambda text: policy.render(router, text)


def stale(update: bool = False) -> list[Path]:
    """The derived files that are not current (rewritten when ``update``)."""
    out = []
    for path, render in derived():
        if not path.exists():
            continue
        text = path.read_text(encoding="utf-8")
        new = render(text)
        if new != text:
            out.append(path)
            if update:
                path.write_text(new, encoding="utf-8")
    return out
