"""Where a run came from: the command, the git commit of the checkout, the library versions
and the CPU."""

from __future__ import annotations

import functools
import os
from pathlib import Path

__all__ = [
    "cpu_description",
    "cpu_kind",
    "git_info",
    "library_versions",
    "portable_command",
    "portable_path",
    "usable_cores",
]

_TRACKED_LIBRARIES = (
    "softtrack",
    "numpy",
    "scipy",
    "numba",
    "torch",
    "stable_baselines3",
    "sbx-rl",
    "jax",
    "gymnasium",
    "pyelastica",
    "pydantic",
    "pyarrow",
)


_PROGRAMS = ("softtrack", "softtrack/cli.py", "softtrack/__main__.py")
#: Whether this process runs softtrack's command line (:func:`mark_cli`).
_cli_running = False


def mark_cli() -> None:
    """Note that this process runs softtrack's command line, so that the command lines it
    records name the program ``softtrack`` also when Python started it with ``-c`` (e.g.
    ``python -c "from softtrack.cli import app; app()" train ...`` in a second checkout)."""
    global _cli_running
    _cli_running = True


def portable_path(path: str | os.PathLike[str], cwd: str | os.PathLike[str] | None = None) -> str:
    """``path`` as it can be recorded in committed files: never absolute. A relative path (or
    one starting with ``~``) stays as given, normalised; an absolute one becomes relative to
    ``cwd`` (default: the current directory), with ``..`` where it lies outside.

    In a checkout at ``/work/REPO``: ``/work/REPO/experiments/a.yaml`` →
    ``experiments/a.yaml``, ``/work/scratch/runs`` → ``../scratch/runs``, ``../other/x.yaml``
    and ``~/runs`` stay as they are.
    """
    text = os.fspath(path)
    if text.startswith("~"):
        return text
    base = os.path.abspath(os.fspath(cwd) if cwd is not None else os.getcwd())
    if not os.path.isabs(text):
        return os.path.normpath(text)
    return os.path.relpath(os.path.normpath(text), base)


def portable_command(
    argv: list[str] | tuple[str, ...], cwd: str | os.PathLike[str] | None = None
) -> list[str]:
    """A command line as run.json and reports record it: the program ``softtrack`` (however it
    was started: ``.venv/bin/softtrack``, ``python -m softtrack.cli``, ``/abs/softtrack/cli.py``;
    another program keeps only its file name) and no absolute path among the arguments (each
    is made relative to ``cwd``, also in ``--option=PATH``: :func:`portable_path`), e.g.
    ``["softtrack", "train", "experiments/study/td3-64-1e7.yaml", "--runs-dir",
    "../scratch/runs"]``.
    """
    if not argv:
        return []
    program = os.fspath(argv[0]).replace(os.sep, "/")
    if any(program == p or program.endswith("/" + p) for p in _PROGRAMS) or (
        program == "-c" and _cli_running
    ):
        program = "softtrack"
    else:
        program = os.path.basename(program) or program
    out = [program]
    for arg in argv[1:]:
        arg = os.fspath(arg)
        option, eq, value = arg.partition("=")
        if arg.startswith("-") and eq and os.path.isabs(value):
            out.append(f"{option}={portable_path(value, cwd)}")
        elif not arg.startswith("-") and os.path.isabs(arg):
            out.append(portable_path(arg, cwd))
        else:
            out.append(arg)
    return out


#: Paths (from the checkout's root) of results, not code: changes there leave a run's
#: ``git_dirty`` false (a shipped run exported while others train is not a code change).
RESULT_PATHS = ("models", "reports", "docs")


@functools.cache
def git_info(directory: str | None = None) -> tuple[str | None, bool | None]:
    """``(commit, dirty)`` of the git checkout containing ``directory`` (default: the
    softtrack package), or ``(None, None)`` outside git or without a git executable.

    ``dirty`` is true when tracked files differ from the commit or untracked (non-ignored)
    files exist, outside the results the project writes and ships (:data:`RESULT_PATHS`:
    exported runs, reports, documentation), which cannot change what a run trains. Read-only:
    ``--no-optional-locks`` keeps ``git status`` from touching the index.
    """
    import subprocess  # here, like platform and importlib.metadata: a query needs none

    cwd = directory or str(Path(__file__).resolve().parents[1])
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            check=False,
            cwd=cwd,
            capture_output=True,
            text=True,
            timeout=10,
        )
        if commit.returncode != 0:
            return None, None
        status = subprocess.run(
            [
                "git",
                "--no-optional-locks",
                "status",
                "--porcelain",
                "--",
                ".",
                *(f":(exclude){path}" for path in RESULT_PATHS),
            ],
            check=False,
            cwd=cwd,
            capture_output=True,
            text=True,
            timeout=30,
        )
    except (OSError, subprocess.SubprocessError):
        return None, None
    dirty = bool(status.stdout.strip()) if status.returncode == 0 else None
    return commit.stdout.strip() or None, dirty


def library_versions() -> dict[str, str]:
    """Versions of Python and the installed libraries that matter for results.

    Uses package metadata only (no imports, so torch is not loaded); absent ones are left out.
    """
    import importlib.metadata
    import platform

    versions = {"python": platform.python_version()}
    for name in _TRACKED_LIBRARIES:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            continue
    return versions


_VECTOR_EXTENSIONS = ("avx512f", "avx2", "avx", "neon", "asimd")


def usable_cores() -> int:
    """The number of logical cores this process may run on (its affinity mask where known)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover (not Linux)
        return max(1, os.cpu_count() or 1)


def cpu_description(cpuinfo: str = "/proc/cpuinfo") -> str:
    """CPU model, logical cores usable by this process and widest vector extension.

    Training throughput depends on these (the learning step is ~97 % of a TD3 step), so runs
    and benchmarks record them, e.g. ``"AMD EPYC, 2 cores, avx2"``. Where ``cpuinfo`` cannot be
    read (not Linux), the model comes from :func:`platform.processor` and the extension is left
    out.
    """
    model, widest = _cpu_model_and_extension(cpuinfo)
    cores = usable_cores()
    parts = [model, f"{cores} core{'s' if cores != 1 else ''}"]
    return ", ".join(parts + ([widest] if widest else []))


def cpu_kind(cpuinfo: str = "/proc/cpuinfo") -> str:
    """CPU model and widest vector extension, e.g. ``"AMD EPYC, avx512f"``: what decides the
    floating-point rounding of a deterministic evaluation (the compiled kernels differ by
    extension), so evaluation tables record it beside their numbers."""
    model, widest = _cpu_model_and_extension(cpuinfo)
    return ", ".join([model] + ([widest] if widest else []))


def _cpu_model_and_extension(cpuinfo: str) -> tuple[str, str | None]:
    import platform

    model = ""
    flags: set[str] = set()
    try:
        with open(cpuinfo, encoding="utf-8", errors="replace") as handle:
            for line in handle:
                key, _, value = line.partition(":")
                key = key.strip()
                if key in ("model name", "Model", "cpu model") and not model:
                    model = value.strip()
                elif key in ("flags", "Features") and not flags:
                    flags = set(value.split())
                if model and flags:
                    break
    except OSError:
        pass
    model = model or platform.processor() or platform.machine() or "unknown CPU"
    return model, next((ext for ext in _VECTOR_EXTENSIONS if ext in flags), None)
