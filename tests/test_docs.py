"""The command examples in the README and docs/ print what the docs show: every
``$ softtrack query ...`` and ``$ softtrack validate ...`` in a code block is run (queries on the
shipped runs) and its output compared line for line with the text beneath it (a shown number or
error is the one the command prints). The other commands of the README's tour run in
tests/test_readme_commands.py."""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest
from typer.testing import CliRunner

from softtrack.cli import app

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
_COMMANDS = ("$ softtrack query", "$ softtrack validate")  # fast and read-only


def _blocks(text: str) -> list[str]:
    """The bodies of the fenced code blocks without a language or marked ``console``."""
    blocks, body, info = [], None, ""
    for line in text.splitlines():
        if body is None and line.startswith("```"):
            body, info = [], line[3:].strip()
        elif body is not None and line.strip() == "```":
            if info in ("", "console"):
                blocks.append("\n".join(body))
            body = None
        elif body is not None:
            body.append(line)
    return blocks


def _examples() -> list[tuple[str, str, list[str], list[str]]]:
    """(file, command text, argv, expected output lines) of every query example."""
    found = []
    for path in DOCS:
        for block in _blocks(path.read_text(encoding="utf-8")):
            lines = block.splitlines()
            k = 0
            while k < len(lines):
                if not lines[k].startswith(_COMMANDS):
                    k += 1
                    continue
                text = lines[k][2:]
                k += 1
                while True:  # the command goes on until its quotes close
                    try:
                        words = shlex.split(text)
                        break
                    except ValueError:
                        text += "\n" + lines[k]
                        k += 1
                output = []
                while k < len(lines) and not lines[k].startswith("$ "):
                    output.append(lines[k])
                    k += 1
                found.append((path.name, text, words, output))
    return found


EXAMPLES = _examples()


def test_the_docs_have_query_examples() -> None:
    assert len(EXAMPLES) >= 8
    assert any(words[1] == "validate" for _, _, words, _ in EXAMPLES)


@pytest.mark.parametrize(
    ("doc", "text", "words", "expected"),
    EXAMPLES,
    ids=[f"{e[0]}:{i}" for i, e in enumerate(EXAMPLES)],
)
def test_query_example_prints_what_the_docs_show(
    doc: str, text: str, words: list[str], expected: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(ROOT)
    head = None
    if "|" in words:  # `... | head -N`
        pipe = words.index("|")
        assert words[pipe + 1] == "head", text
        head = int(words[pipe + 2].lstrip("-"))
        words = words[:pipe]
    assert words[0] == "softtrack" and words[1] in ("query", "validate"), text
    result = CliRunner().invoke(app, words[1:])
    error = bool(expected) and expected[0].startswith("error:")
    assert result.exit_code == (2 if error else 0), result.output
    printed = (result.stderr if error else result.stdout).splitlines()
    if head is not None:
        printed = printed[:head]
    assert [line.rstrip() for line in printed] == [line.rstrip() for line in expected], (
        f"{doc}: `{text}` prints something else; update the doc from the command's output"
    )


def test_the_readme_stays_a_front_page() -> None:
    """Issue 61: the README is a front page (≤ 200 lines), its results one table of ≤ 10 rows;
    the detail lives in docs/."""
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 200, len(lines)
    tables: list[int] = []
    previous = ""
    for line in lines:
        if line.startswith("|") and not previous.startswith("|"):
            tables.append(0)
        if line.startswith("|") and not set(line) <= set("|-: "):
            tables[-1] += 1
        previous = line
    assert tables and max(tables) - 1 <= 10, tables  # rows below the header
