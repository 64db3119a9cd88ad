"""The code's shape that issue 61 asks for: no function longer than 120 lines."""

from __future__ import annotations

import ast
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "softtrack"
MAX_LINES = 120


def _long_functions() -> dict[str, int]:
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = (node.end_lineno or node.lineno) - node.lineno + 1
                if lines > MAX_LINES:
                    found[f"{path.relative_to(PACKAGE).as_posix()}:{node.name}"] = lines
    return found


def test_no_function_is_longer_than_120_lines() -> None:
    long = _long_functions()
    assert not long, long


def test_the_engine_recipe_names_functions_that_exist() -> None:
    """CONTRIBUTING.md's "Change the engine" names the structures and stages of the step."""
    text = (PACKAGE.parent / "CONTRIBUTING.md").read_text(encoding="utf-8")
    section = text.split("## Change the engine", 1)[1].split("\n## ", 1)[0]
    sources = "".join(p.read_text(encoding="utf-8") for p in (PACKAGE / "sim").glob("*.py"))
    names = {
        n for n in re.findall(r"`([A-Za-z_][A-Za-z_]+)`", section) if "_" in n or n[0].isupper()
    }
    defined = set(re.findall(r"^(?:def|class) (\w+)", sources, flags=re.MULTILINE))
    defined |= set(re.findall(r"^    def (\w+)", sources, flags=re.MULTILINE))
    assert {"BatchState", "_compute_internal_stresses", "rod_rod_contact"} <= names
    assert names <= defined | {"RodBatch.advance"}, names - defined
