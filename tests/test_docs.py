"""The code base cites only documents it carries.

Comments, docstrings and docs must point a reader to the repository's own documents
(``docs/protocol.md`` for the arm, its protocol and the thesis; ``docs/architecture.md``;
``docs/deployment.md``; the README), never to a file outside it (a specification digest,
a style guide, a brief, the thesis by its section numbers). A citation of a section,
``docs/<file>.md, <Heading>`` or ``README, <Heading>``, must name a heading of that file.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
PROTOCOL = DOCS / "protocol.md"

SCANNED_DIRS = ("manus", "schemas", "services", "manus_stack", "examples", "tests", "deploy",
                "docs", "paths")  # fmt: skip
SCANNED_FILES = ("README.md", "compose.yaml", "pyproject.toml")
TEXT_SUFFIXES = {".py", ".md", ".json5", ".json", ".yaml", ".yml", ".toml", ".dbc", ".urdf",
                 ".txt", ".cfg", ""}  # fmt: skip
SKIPPED = {Path(__file__).resolve()}
"""This file spells the forbidden patterns to look for them."""

OUTSIDE = [
    (re.compile(r"\bSPEC\b"), "the specification digest is not in the repository"),
    (re.compile(r"\bSTYLE(?:\.md|\s+\d)"), "the style guide is not in the repository"),
    (re.compile(r"\b(?:team|task|lead's|the)\s+brief\b|\bbrief's\b", re.I), "a brief"),
    (re.compile(r"\bcontract\s+\d", re.I), "a numbered contract of a brief"),
    (re.compile(r"shared/|/work/|seed/\d|000_2b02af0a8b5be651"), "a file outside the repository"),
]
"""(pattern, what it points to) for citations of documents outside the repository."""

THESIS_NUMBERS = [
    re.compile(
        r"\bthesis(?:'s)?\s+(?:own\s+|printed\s+)?(?:\d+(?:\.\d+)+\b|§"
        r"|(?:tables?|figures?|fig\.|eqs?|eq\.|equations?|listings?|sections?|chapters?)\s*\d)",
        re.I,
    ),
    re.compile(
        r"\b(?:tables?|figures?|listings?|eqs?|equations?|sections?|chapters?)\s+\d[\d.]*"
        r"(?:\s*-\s*[\d.]+)?\s+of\s+the\s+thesis",
        re.I,
    ),
    re.compile(r"\beqs?\.?\s+\d"),
    re.compile(r"\b(?:Table|Figure|Listing)s?\s+\d+\.\d"),
]
"""The thesis cited by its own numbers: only docs/protocol.md may (it carries them)."""

ALLOWED: dict[str, list[str]] = {}
"""Offenders left in files being rewritten elsewhere: path -> texts of offending lines.
Each entry must still be found (an entry that no longer matches fails too), so the list
empties as the files are fixed."""

CITATION = re.compile(r"(?:\bdocs/(?P<doc>[\w-]+\.md)|\b(?P<readme>README)(?:\.md)?)`?,[ \t]*")
DOC_NAME = re.compile(r"\bdocs/([\w-]+\.md)\b")
CONTINUATION = re.compile(r"\s*\n\s*(?:#+|//|\*)?\s*")


def scanned_files() -> list[Path]:
    """Every text file of the scanned parts of the repository."""
    out = [ROOT / name for name in SCANNED_FILES if (ROOT / name).exists()]
    for d in SCANNED_DIRS:
        for path in sorted((ROOT / d).rglob("*")):
            parts = set(path.relative_to(ROOT).parts)
            if not path.is_file() or parts & {"__pycache__", "data"}:
                continue
            if path.suffix in TEXT_SUFFIXES and path.resolve() not in SKIPPED:
                out.append(path)
    return out


def headings(doc: Path) -> set[str]:
    """The headings of a markdown file (outside code fences), also without a trailing
    parenthesis: ``Two computers (docs/deployment.md)`` is cited as ``Two computers``."""
    out: set[str] = set()
    fenced = False
    for line in doc.read_text().splitlines():
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and (m := re.match(r"#{1,6}\s+(.+?)\s*#*\s*$", line)):
            text = m.group(1)
            out.add(text)
            out.add(re.sub(r"\s*\([^)]*\)$", "", text))
    return out


def _line(text: str, pos: int) -> int:
    return text.count("\n", 0, pos) + 1


def _rel(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def test_the_scan_sees_the_code_base() -> None:
    names = {_rel(p) for p in scanned_files()}
    expected = {"README.md", "manus/protocol.py", "docs/protocol.md", "deploy/Dockerfile",
                "schemas/manus.dbc", "paths/thesis_square.txt", "tests/conftest.py"}  # fmt: skip
    assert expected <= names


def test_no_citation_of_a_document_outside_the_repository() -> None:
    found: dict[str, list[str]] = {}
    problems = []
    for path in scanned_files():
        text = path.read_text(errors="replace")
        rel = _rel(path)
        patterns = list(OUTSIDE)
        if path != PROTOCOL:
            patterns += [(p, "the thesis by its numbers (cite docs/protocol.md)")
                         for p in THESIS_NUMBERS]  # fmt: skip
        for pattern, what in patterns:
            for m in pattern.finditer(text):
                line = text.splitlines()[_line(text, m.start()) - 1].strip()
                allowed = [t for t in ALLOWED.get(rel, []) if t in line]
                if allowed:
                    found.setdefault(rel, []).extend(allowed)
                    continue
                problem = f"{rel}:{_line(text, m.start())}: {what}: {line}"
                if problem not in problems:
                    problems.append(problem)
    assert not problems, "cite the repository's own docs instead:\n" + "\n".join(problems)
    stale = [f"{rel}: {t!r}" for rel, texts in ALLOWED.items() for t in texts
             if t not in found.get(rel, [])]  # fmt: skip
    assert not stale, "ALLOWED entries that no longer occur (remove them):\n" + "\n".join(stale)


def test_every_cited_doc_exists() -> None:
    problems = []
    for path in scanned_files():
        text = path.read_text(errors="replace")
        for m in DOC_NAME.finditer(text):
            if not (DOCS / m.group(1)).is_file():
                problems.append(f"{_rel(path)}:{_line(text, m.start())}: no docs/{m.group(1)}")
    assert not problems, "\n".join(problems)


def test_every_cited_section_is_a_heading() -> None:
    known = {p.name: headings(p) for p in DOCS.glob("*.md")}
    known["README"] = headings(ROOT / "README.md")
    problems = []
    count = 0
    for path in scanned_files():
        text = path.read_text(errors="replace")
        for m in CITATION.finditer(text):
            doc = m.group("doc") or "README"
            if doc not in known:
                continue  # test_every_cited_doc_exists reports it
            cited = CONTINUATION.sub(" ", text[m.end() : m.end() + 200]).lstrip("\"'`")
            if not cited[:1].isupper():
                continue  # prose ("docs/deployment.md, which ..."), not a section
            count += 1
            if not any(
                cited.startswith(h) and not cited[len(h) : len(h) + 1].isalnum() for h in known[doc]
            ):
                where = f"{_rel(path)}:{_line(text, m.start())}"
                problems.append(f"{where}: {doc}, {cited[:40]!r}... names no heading of {doc}")
    assert not problems, "\n".join(problems)
    assert count > 0


def test_protocol_headings_are_unique() -> None:
    seen: list[str] = []
    fenced = False
    for line in PROTOCOL.read_text().splitlines():
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and (m := re.match(r"#{1,6}\s+(.+)", line)):
            seen.append(m.group(1).strip())
    duplicates = sorted({h for h in seen if seen.count(h) > 1})
    assert not duplicates, f"docs/protocol.md headings cited by name must be unique: {duplicates}"


@pytest.mark.parametrize(
    ("text", "bad"),
    [
        ("see SPEC 3.2", True),
        ("(thesis 4.2.3.4)", True),
        ("thesis Table 4.1", True),
        ("the thesis's eqs 3.6/3.8", True),
        ("Listing 5.1 of the thesis", True),
        ("the team brief's contract 4", True),
        ("Layers (STYLE 9)", True),
        ("/work/shared/SPEC.md", True),
        ("the thesis's square (docs/protocol.md, Thesis test paths)", False),
        ("the thesis mode", False),
        ("l1: shoulder offset [m] (thesis 105 mm)", False),
        ("next to the thesis's figures (5 mm mean)", False),
        ("a brief pause", False),
    ],
)
def test_the_patterns(text: str, bad: bool) -> None:
    patterns = [p for p, _ in OUTSIDE] + THESIS_NUMBERS
    assert any(p.search(text) for p in patterns) == bad
