"""The `softtrack query` examples in the README and docs/ print what the docs show: every
``$ softtrack query ...`` in a ``console`` block is run on the shipped runs and its output
compared line for line with the text beneath it (a shown number is the one the command prints)."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest
from typer.testing import CliRunner

from softtrack.cli import app

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
_BLOCK = re.compile(r"^```console\n(.*?)^```", re.S | re.M)


def _examples() -> list[tuple[str, str, list[str], list[str]]]:
    """(file, command text, argv, expected output lines) of every query example."""
    found = []
    for path in DOCS:
        for block in _BLOCK.findall(path.read_text(encoding="utf-8")):
            lines = block.splitlines()
            k = 0
            while k < len(lines):
                if not lines[k].startswith("$ softtrack query"):
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
    assert len(EXAMPLES) >= 7


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
    assert words[:2] == ["softtrack", "query"], text
    result = CliRunner().invoke(app, words[1:])
    assert result.exit_code == 0, result.output
    printed = result.stdout.splitlines()
    if head is not None:
        printed = printed[:head]
    assert [line.rstrip() for line in printed] == [line.rstrip() for line in expected], (
        f"{doc}: `{text}` prints something else; update the doc from the command's output"
    )
