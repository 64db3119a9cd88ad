"""``softtrack quickstart``: train, evaluate and report the quickstart experiment beside the
shipped policy; where the quickstart spec and the shipped run are found."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path

from softtrack.spec import (
    SpecError,
)
from softtrack.store.location import QUICKSTART_PRETRAINED
from softtrack.workflows.evaluate_runs import evaluate
from softtrack.workflows.report_runs import report
from softtrack.workflows.shipped_runs import copy_run
from softtrack.workflows.training_runs import train


def _checkout_or_cwd(relative: str) -> list[Path]:
    """``relative`` in this source checkout (an editable install) and in the current
    directory (a checkout the user works in with an installed wheel), in that order."""
    return [Path(__file__).resolve().parents[2] / relative, Path.cwd() / relative]


def quickstart_pretrained_path() -> Path | None:
    """The :data:`QUICKSTART_PRETRAINED` run directory of this checkout or of the current
    directory, or ``None`` if neither has it (an installed wheel used elsewhere)."""
    for path in _checkout_or_cwd(QUICKSTART_PRETRAINED):
        if (path / "run.json").is_file():
            return path
    return None


def quickstart_spec_path() -> Path:
    """``experiments/quickstart.yaml`` of this checkout or the current directory, else the
    copy that ships inside the package (``softtrack/data/quickstart.yaml``)."""
    from importlib.resources import files

    for path in _checkout_or_cwd("experiments/quickstart.yaml"):
        if path.is_file():
            return path
    packaged = Path(str(files("softtrack") / "data" / "quickstart.yaml"))
    if not packaged.is_file():
        raise SpecError(
            str(packaged),
            "the quickstart spec is missing from this installation",
            "reinstall softtrack (pip install softtrack) or run from a checkout",
        )
    return packaged


def quickstart(
    overrides: Sequence[str] = (),
    out: str | os.PathLike[str] = "reports/quickstart",
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    pretrained: str | os.PathLike[str] | None = None,
    no_pretrained: bool = False,
    on_line: Callable[[str], None] = print,
    on_episode: Callable[..., None] | None = None,
) -> tuple[Path | None, int]:
    """Train, evaluate and report the quickstart experiment (``softtrack quickstart``).

    Trains :func:`quickstart_spec_path` (with ``overrides``), evaluates it on the three
    trajectories, evaluates the shipped policy (``pretrained``, default
    :func:`quickstart_pretrained_path`; none with ``no_pretrained``) in a copy in the runs
    directory (the shipped directory is only read), and reports both into ``out``.

    Args:
        on_line: called with each step's line ("1/4 training …").
        on_episode: called after each evaluation episode (as :func:`evaluate`).

    Returns:
        (the report's ``index.md``, 0), or (None, the training's exit code) when the training
        did not complete.

    Raises:
        SpecError: ``pretrained`` is not a run directory, or the quickstart spec is missing.
    """
    shipped = None
    if not no_pretrained:
        shipped = Path(pretrained) if pretrained is not None else quickstart_pretrained_path()
    if shipped is not None and not (shipped / "run.json").is_file():
        raise SpecError(
            "quickstart",
            f"--pretrained {shipped} is not a run directory (no run.json)",
            "give a directory made by `softtrack export`, or --no-pretrained",
        )
    spec_path = quickstart_spec_path()
    copy = None if shipped is None else copy_run(shipped, runs_dir=runs_dir)
    on_line(f"1/4 training {shown_path(spec_path)} (progress on stderr)")
    outcomes = train(
        spec_path,
        overrides,
        runs_dir=runs_dir,
        on_start=lambda record: on_line(f"    run {record.run_id}"),
    )
    if not outcomes or outcomes[-1].status != "completed":
        return None, max((o.exit_code for o in outcomes), default=1)
    run_ids = [o.run_id for o in outcomes]
    on_line("2/4 evaluating on circle, rectangle, figure8")
    evaluate(run_ids, runs_dir=runs_dir, on_episode=on_episode)
    extra: list[Path] = []
    if shipped is None or copy is None:
        on_line(
            "3/4 no shipped policy to show (skipped: --no-pretrained)"
            if no_pretrained
            else f"3/4 no shipped policy to show: {QUICKSTART_PRETRAINED} is neither in a "
            "checkout nor in the current directory (an installed softtrack used elsewhere); "
            "give --pretrained DIR, that directory of a clone, to compare with it"
        )
    else:
        on_line(
            f"3/4 the shipped policy {shown_path(shipped)} on the same trajectories "
            f"(evaluated in its copy {shown_path(copy)})"
        )
        evaluate([str(copy)], on_episode=on_episode)
        extra = [copy]
    on_line("4/4 building the report")
    index = report(
        run_ids,
        out,
        runs_dir=runs_dir,
        extra_runs=extra,
        command_line=["softtrack", "quickstart", "--out", str(out)],
    )
    return Path(index), 0


def shown_path(path: str | os.PathLike[str]) -> str:
    """``path`` relative to the current directory when it lies inside it, else absolute."""
    full = Path(path).resolve()
    return str(full.relative_to(Path.cwd())) if full.is_relative_to(Path.cwd()) else str(full)
