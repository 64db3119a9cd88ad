"""The code's shape that issue 61 asks for: no function longer than 120 lines, except the
engine's contact kernel (see KNOWN_LONG)."""

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


#: The contact kernel (and its builder). Its contact stages take their arrays one by one:
#: passed as tuples (even built once) or wrapped in one more inlined stage, the contact and
#: sphere steps ran 12-19 % slower (session 26, benchmarks/bench_engine_versions.py;
#: softtrack/sim/kernels.py's docstring). The test fails when one of them shrinks under the
#: limit (remove it here) or any other function grows past it.
KNOWN_LONG = {
    "sim/kernels.py:_build_advance_contact",
    "sim/kernels.py:advance_contact",
}


def test_no_function_is_longer_than_120_lines() -> None:
    long = _long_functions()
    assert not set(long) - KNOWN_LONG, {k: v for k, v in long.items() if k not in KNOWN_LONG}
    assert not KNOWN_LONG - set(long), "a kernel is short now: remove it from KNOWN_LONG"


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
