"""No import runs back up a layer: each package of softtrack imports only the packages below
it (function-local imports included), so the domain code never depends on training, reports
or the command line."""

from __future__ import annotations

import ast
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "softtrack"

#: bottom to top; a package may import those of lower layers only
LAYERS: list[set[str]] = [
    {"lazy", "signals", "numbers", "trajectories"},
    {"sim", "viz"},
    {"env"},
    {"mpc"},
    {"spec"},
    {"store"},
    {"executors"},
    {"evaluation"},
    {"report", "rl"},
    {"tune"},
    {"cli_classes"},
    {"api", "workers"},
    {"commands"},
    {"cli", "__init__", "__main__"},
]
LAYER = {name: level for level, names in enumerate(LAYERS) for name in names}


def _imported_packages(path: Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        names = []
        if isinstance(node, ast.ImportFrom) and node.module == "softtrack" and node.level == 0:
            names = [f"softtrack.{alias.name}" for alias in node.names]  # from softtrack import api
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]
        elif isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        for name in names:
            parts = name.split(".")
            if parts[0] == "softtrack" and len(parts) > 1:
                found.add(parts[1])
    return found


def test_every_package_has_a_layer() -> None:
    packages = {
        p.name if p.is_dir() else p.stem
        for p in PACKAGE.iterdir()
        if (p.is_dir() and (p / "__init__.py").is_file()) or p.suffix == ".py"
    }
    assert packages <= set(LAYER), sorted(packages - set(LAYER))


def test_no_import_runs_up_a_layer() -> None:
    upward = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).parts
        own = rel[0] if len(rel) > 1 else path.stem
        for imported in _imported_packages(path) - {own}:
            if LAYER.get(imported, -1) >= LAYER[own] and imported != own:
                upward.append(f"{path.relative_to(PACKAGE.parent)} imports softtrack.{imported}")
    assert not upward, "\n".join(upward)


def test_file_names_are_unique_across_the_package() -> None:
    """A module's name says what it holds: no two modules share a file name (``__init__.py``
    aside), so ``runs.py`` or ``tables.py`` never needs its package to be understood."""
    seen: dict[str, list[str]] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.name != "__init__.py" and "__pycache__" not in path.parts:
            seen.setdefault(path.name, []).append(str(path.relative_to(PACKAGE)))
    assert {name: paths for name, paths in seen.items() if len(paths) > 1} == {}


def test_contributing_lists_the_layers_in_their_order() -> None:
    """CONTRIBUTING.md's layer map names the packages of :data:`LAYERS`, bottom to top."""
    text = (PACKAGE.parent / "CONTRIBUTING.md").read_text(encoding="utf-8")
    section = text.split("## The layers", 1)[1].split("\n## ", 1)[0]
    listed = [
        set(re.findall(r"`(\w+)`", line.split(":", 1)[0]))
        for line in section.splitlines()
        if re.match(r"\d+\. ", line)
    ]
    assert listed == [names - {"__init__", "__main__"} for names in LAYERS]


def test_contributing_names_files_that_exist() -> None:
    text = (PACKAGE.parent / "CONTRIBUTING.md").read_text(encoding="utf-8")
    named = set(re.findall(r"`((?:softtrack|tests)/[\w/]+\.py)`", text))
    assert named and sorted(p for p in named if not (PACKAGE.parent / p).is_file()) == []
