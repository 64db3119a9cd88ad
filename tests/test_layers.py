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
    {"lazy", "signals", "numbers", "trajectories", "file_kinds"},
    {"sim", "viz"},
    {"env"},
    {"mpc"},
    {"spec"},
    {"store"},
    {"executors"},
    {"evaluation"},
    {"report", "rl"},
    {"tune"},
    {"workflows"},
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


def _module_graph() -> dict[str, set[str]]:
    """softtrack's modules and the softtrack modules each imports, by every import form (top,
    function-local, ``TYPE_CHECKING``, relative); a package is its ``__init__``."""
    modules = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
        found = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join([*base, node.module or ""]) if node.level else node.module or ""
                module = module.rstrip(".")
                found |= {
                    f"{module}.{alias.name}" if f"{module}.{alias.name}" in modules else module
                    for alias in node.names
                }
            elif isinstance(node, ast.Import):
                found |= {alias.name for alias in node.names}
        graph[name] = {m for m in found if m in modules and m != name}
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[frozenset[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(frozenset(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_module_import_cycle() -> None:
    assert [sorted(c) for c in _cycles(_module_graph())] == []


def test_the_cycle_finder_sees_type_only_and_local_imports() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _cycles(graph) == [frozenset({"a", "b", "c"})]
    assert "softtrack.sim.rod_properties" in _module_graph()["softtrack.sim.stability"]


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


def test_the_command_line_starts_without_the_heavy_packages() -> None:
    """`softtrack --help` (issue 59: at once) imports no spec models, engine or array library:
    each command loads them when it runs."""
    import subprocess
    import sys

    code = (
        "import sys, softtrack.cli\n"
        "heavy = ['softtrack.spec', 'softtrack.sim', 'numba', 'numpy', 'pandas', 'jax', 'torch']\n"
        "print(' '.join(m for m in heavy if m in sys.modules))\n"
    )
    loaded = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.split()
    assert loaded == [], f"softtrack.cli imports {loaded} at start"


#: At most this many function-local imports of softtrack (issue 61: imports at the top
#: except a documented few; 68 before): each keeps torch, JAX, matplotlib, SciPy's statistics,
#: submitit or DuckDB out of `import softtrack.api` and `softtrack --help`, or the spec models
#: out of the catalog.
MAX_LOCAL_IMPORTS = 27


def _local_imports() -> list[tuple[str, int, bool]]:
    """(file, line, documented) of each function-local import of softtrack: documented when
    its line, or the comment line just above its block of imports, says why."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        lines = path.read_text(encoding="utf-8").splitlines()
        for function in ast.walk(ast.parse("\n".join(lines))):
            if not isinstance(function, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(function):
                names = (
                    [node.module or ""]
                    if isinstance(node, ast.ImportFrom)
                    else [a.name for a in node.names]
                    if isinstance(node, ast.Import)
                    else []
                )
                if not any(n.split(".")[0] == "softtrack" for n in names):
                    continue
                above = node.lineno - 2
                while above >= 0 and lines[above].strip().startswith(
                    ("from softtrack", "import softtrack")
                ):
                    above -= 1
                documented = "#" in lines[node.lineno - 1] or lines[above].strip().startswith("#")
                found.append((str(path.relative_to(PACKAGE)), node.lineno, documented))
    return found


def test_imports_are_at_the_top_except_a_documented_few() -> None:
    local = _local_imports()
    assert [f"{p}:{n}" for p, n, documented in local if not documented] == []
    assert len(local) <= MAX_LOCAL_IMPORTS, [f"{p}:{n}" for p, n, _ in local]


def test_the_api_loads_without_the_learners_and_plots() -> None:
    """`import softtrack.api` (what every command that trains, evaluates or reports loads
    first) stays free of the learners, plots, tuning and the results database: they load
    when used (the documented local imports above)."""
    import subprocess
    import sys

    heavy = [
        "torch",
        "jax",
        "stable_baselines3",
        "matplotlib",
        "optuna",
        "scipy.stats",
        "duckdb",
        "mlflow",
        "submitit",
    ]
    code = f"import sys, softtrack.api\nprint(' '.join(m for m in {heavy!r} if m in sys.modules))\n"
    loaded = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.split()
    assert loaded == [], f"import softtrack.api loads {loaded}"
