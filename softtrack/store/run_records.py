"""A run's record: ``run.json`` (:class:`RunInfo`), read and checked, and the paths and files of
a run directory (:class:`RunRecord`). The reading half of :mod:`softtrack.store.runs`, whose
:class:`~softtrack.store.runs.RunStore` creates, finds and updates runs; the catalog's row
reader (:mod:`softtrack.store.catalog_rows`) reads runs through this module alone.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from softtrack.env.tasks import N_ARMS
from softtrack.file_kinds import read_regular_file
from softtrack.spec import (
    ExperimentSpec,
    SpecError,
    load_spec,
)
from softtrack.spec.fields import check_int64
from softtrack.store.errors import RunStoreError, unreadable_fix
from softtrack.store.layout import PolicyDir
from softtrack.store.liveness import LOCK_NAME

__all__ = [
    "MAX_RUN_JSON_BYTES",
    "RUN_FORMAT_VERSION",
    "RUN_STATUSES",
    "RunInfo",
    "RunRecord",
    "RunStatus",
    "UnreadableRun",
    "iso_value",
    "read_run_info",
    "read_run_record",
    "utc_now",
]


RUN_STATUSES = ("queued", "running", "completed", "failed", "interrupted")
#: The largest ``run.json`` read (a record is a few kB; a failed run's traceback adds tens).
MAX_RUN_JSON_BYTES = 4_000_000
#: The newest layout of ``run.json`` this softtrack reads and writes.
RUN_FORMAT_VERSION = 1
RunStatus = Literal["queued", "running", "completed", "failed", "interrupted"]


def utc_now() -> str:
    """The current time as ISO 8601 UTC with milliseconds, e.g. ``2025-11-23T09:18:01.123Z``."""
    return datetime.now(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def iso_value(value: Any) -> Any:
    """``value`` as run.json stores it: a datetime as ISO 8601 UTC with milliseconds (``Z``),
    anything else as it is."""
    if isinstance(value, datetime):
        if value.tzinfo is None:
            value = value.replace(tzinfo=UTC)
        return value.astimezone(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")
    return value


class RunInfo(BaseModel):
    """The content of ``run.json``. Unknown keys written by newer code are kept."""

    model_config = ConfigDict(extra="allow", validate_assignment=True)

    format_version: int = Field(RUN_FORMAT_VERSION, description="version of this file's layout")
    run_id: str = Field(description="ULID of the run (= its directory name)")
    name: str = Field(
        description="experiment name (spec.name: letters, digits, '_', '-', '.'; a name "
        "edited into another shape makes the run unreadable rather than break tables and "
        "reports)",
        pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$",
    )
    algo: str = Field(description="algorithm (spec.algo.name)")
    controller: str = Field(description="centralized or independent")
    seed: int = Field(description="random seed of this run")
    status: RunStatus = Field(
        "queued", description="queued, running, completed, failed, interrupted"
    )
    created: str = Field(description="creation time, ISO 8601 UTC")
    started: str | None = Field(
        None,
        description="time training first started, ISO 8601 UTC (each session's start: sessions)",
    )
    ended: str | None = Field(None, description="time the run ended, ISO 8601 UTC")
    heartbeat: str | None = Field(None, description="last sign of life of the training process")
    total_timesteps: int = Field(
        ge=0,
        description="training budget of the run, env steps: spec training.total_timesteps, "
        "times 2 for an independent run (that budget per arm)",
    )
    global_step: int = Field(
        0, ge=0, description="env steps done so far (independent: over both arms)"
    )
    arm_total_timesteps: int | None = Field(
        None,
        description="independent runs: budget per arm, env steps (spec training.total_timesteps); "
        "the arms are trained one after the other, arm 0 first",
    )
    arm_steps: list[int] | None = Field(
        None, description="independent runs: env steps done per arm (global_step is their sum)"
    )
    steps_per_second: float | None = Field(None, description="training throughput, env steps/s")
    spec_hash: str = Field(description="softtrack.spec.spec_hash of the spec (seed-independent)")
    git_commit: str | None = Field(
        None,
        description="commit of the softtrack code when the run was created, if in git "
        "(a resumed run may have trained on later commits: see sessions)",
    )
    git_dirty: bool | None = Field(None, description="uncommitted changes in the checkout")
    versions: dict[str, str] = Field(
        default_factory=dict, description="python and library versions"
    )
    command: list[str] = Field(
        default_factory=list,
        description="command line (sys.argv as `softtrack ...`, without absolute paths)",
    )
    host: str | None = Field(None, description="host name of the (last) running process")
    cpu: str | None = Field(
        None,
        description="CPU model, usable cores and vector extension of the (last) running "
        "process (steps_per_second depends on it)",
    )
    pid: int | None = Field(None, description="process id of the (last) running process")
    error: str | None = Field(None, description="one-line error of a failed run")
    traceback: str | None = Field(
        None, description="full traceback of a failed run (shown by `softtrack runs --failed`)"
    )
    sessions: list[dict[str, Any]] = Field(
        default_factory=list,
        description="one entry per training process, oldest first (a resumed run has several): "
        "started, host, cpu, pid, git_commit, git_dirty and, once it ended, ended, end_step (env "
        "steps done), status (lost: the process died unrecorded; ended is its last heartbeat) "
        "and steps_per_second",
    )
    notes: dict[str, Any] = Field(default_factory=dict, description="free-form additions")

    @field_validator("format_version", mode="after")
    @classmethod
    def _known_format(cls, value: int) -> int:
        """A run written by a newer softtrack (a later layout) is not read as this one's."""
        if not 1 <= value <= RUN_FORMAT_VERSION:
            raise ValueError(
                f"run format {value} is not one this softtrack reads (1 to "
                f"{RUN_FORMAT_VERSION}): a newer softtrack wrote it; upgrade softtrack to use it"
            )
        return value

    @field_validator(
        "seed",
        "total_timesteps",
        "global_step",
        "arm_total_timesteps",
        "arm_steps",
        "pid",
        mode="after",
    )
    @classmethod
    def _fits_int64(cls, value: Any) -> Any:
        """Counters fit the store's 64-bit integer columns (``softtrack query``)."""
        check_int64(value)
        return value

    @property
    def policy_budget(self) -> int:
        """The budget of one policy, env steps: an independent run's per-arm budget
        (``arm_total_timesteps``; for a run.json without it, ``total_timesteps`` split over the
        :data:`N_ARMS` arms), else ``total_timesteps``."""
        if self.arm_total_timesteps:
            return self.arm_total_timesteps
        if self.controller == "independent":
            return self.total_timesteps // N_ARMS
        return self.total_timesteps


@dataclass(frozen=True)
class RunRecord:
    """A run directory and its ``run.json`` as read at one moment."""

    run_id: str
    path: Path
    info: RunInfo

    @property
    def spec_path(self) -> Path:
        return self.path / "spec.yaml"

    @property
    def run_json_path(self) -> Path:
        return self.path / "run.json"

    @property
    def model_path(self) -> Path:
        """The final model (SB3 zip)."""
        return self.path / "model.zip"

    @property
    def read_only(self) -> bool:
        """A shipped run (``notes.read_only``, set by ``softtrack export``): commands store
        their results in a copy of it unless told ``--in-place``."""
        return bool(self.info.notes.get("read_only"))

    def saved_steps(self) -> int:
        """Env steps the run's saved files hold (over its policies): a finished arm's
        ``state.json`` step, else the step of the policy's newest checkpoint; 0 for none."""
        total = 0
        for policy in PolicyDir.all_of_run(self.path, self.info.controller == "independent"):
            state = policy.read_state() if policy.arm is not None else None
            if state is not None:
                total += int(state.get("global_step", 0))
                continue
            checkpoints = policy.list_checkpoints()
            if checkpoints:
                total += int(checkpoints[-1].name.removeprefix("step-"))
        return total

    def policy_dir(self, arm: int | None = None) -> PolicyDir:
        """The files of the centralized policy (``arm=None``) or of arm ``arm``'s policy."""
        return PolicyDir.of_run(self.path, arm)

    @property
    def checkpoints_dir(self) -> Path:
        return self.path / "checkpoints"

    def checkpoint_dir(self, global_step: int) -> Path:
        """``checkpoints/step-<12-digit step>/`` (sorts by step); write it with ``atomic_dir``."""
        return self.policy_dir().checkpoint_dir(global_step)

    def list_checkpoints(self) -> list[Path]:
        """Complete checkpoint directories of the centralized policy, oldest first."""
        return self.policy_dir().list_checkpoints()

    @property
    def lock_path(self) -> Path:
        """``run.lock``: held (``flock``) by the process training the run, see :func:`run_lock`."""
        return self.path / LOCK_NAME

    @property
    def tables_dir(self) -> Path:
        return self.path / "tables"

    def check_tables_dir(self) -> None:
        """Raise :class:`RunStoreError` when ``tables`` exists but is not a directory, before
        any work whose results would go there is done."""
        if self.tables_dir.exists() and not self.tables_dir.is_dir():
            raise RunStoreError(
                f"{self.tables_dir} is a file where the run's tables directory belongs: move "
                "it away, then run the command again"
            )

    def table_path(self, name: str) -> Path:
        """``tables/<name>.parquet``, e.g. ``table_path("train_episodes")``."""
        return self.tables_dir / f"{name}.parquet"

    @property
    def log_path(self) -> Path:
        """Text log of the training process."""
        return self.path / "train.log"

    def raw_spec(self) -> dict[str, Any]:
        """``spec.yaml`` as plain data, not validated (so runs of older versions still list);
        ``{}`` if it is missing or unreadable. Parsed with libyaml where available (the
        pure-Python parser costs ~40 ms a run)."""
        import yaml

        loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
        try:
            data = yaml.load(self.spec_path.read_text(encoding="utf-8"), Loader=loader)
        except (OSError, yaml.YAMLError, UnicodeDecodeError):
            return {}
        return data if isinstance(data, dict) else {}

    def spec_problem(self) -> str | None:
        """Why ``spec.yaml`` cannot be read at all (missing, not a file, not UTF-8), as a line
        that says what to do; ``None`` if it reads (whether it validates is :meth:`load_spec`'s
        business)."""
        path = self.spec_path
        try:
            path.read_bytes().decode("utf-8")
        except FileNotFoundError:
            problem = "is missing"
        except UnicodeDecodeError:
            problem = "is not UTF-8 text"
        except OSError as exc:
            problem = f"cannot be read ({exc.strerror or exc})"
        else:
            return None
        return (
            f"{path}: the run's spec {problem}; restore it (a copy of the run, or the "
            f"experiment's YAML) and resume again; run {self.run_id} keeps its status"
        )

    def checkpoint_problem(self) -> str | None:
        """Why the run cannot resume: a policy that trained past its first checkpoint
        (``training.checkpoint_interval`` env steps) has no checkpoints directory (missing,
        or replaced by a file), so resuming would start it again from step 0 and rewrite its
        tables. A line that says what to do, or ``None`` (also before the first checkpoint,
        where a run rightly starts again from step 0, and when the spec is unreadable:
        :meth:`spec_problem` says so)."""
        try:
            interval = int(self.load_spec().training.checkpoint_interval)
        except (RunStoreError, SpecError, ValueError):
            return None
        info = self.info
        independent = info.arm_steps is not None
        steps = list(info.arm_steps) if info.arm_steps is not None else [int(info.global_step)]
        for k, step in enumerate(steps):
            where = self.policy_dir(k if independent else None).checkpoints_dir
            if where.exists() and not where.is_dir():
                problem = "is not a directory"
            elif not where.exists() and step >= interval:
                problem = "is missing"
            else:
                continue
            return (
                f"run {self.run_id}: its checkpoints {where} {problem}, so it cannot resume "
                f"from step {step:,}; restore that directory, or train a new run with "
                f"`softtrack train {self.spec_path}` (nothing was changed)"
            )
        return None

    def load_spec(self) -> ExperimentSpec:
        """The run's fully resolved spec.

        Raises:
            RunStoreError: ``spec.yaml`` is missing or unreadable (:meth:`spec_problem`).
            SpecError: it no longer validates.
        """
        problem = self.spec_problem()
        if problem is not None:
            raise RunStoreError(problem)
        return load_spec(self.spec_path)


@dataclass(frozen=True)
class UnreadableRun:
    """A run directory whose ``run.json`` is missing or unreadable (``softtrack runs`` lists it
    as ``unreadable``; nothing else can use it until run.json is restored)."""

    path: Path
    reason: str

    @property
    def fix(self) -> str:
        return unreadable_fix(self.path)


def read_run_info(path: Path) -> RunInfo:
    """The :class:`RunInfo` of the run directory ``path`` (its ``run.json``, read now).

    Raises:
        RunStoreError: ``run.json`` is missing, too large or unreadable (one line naming it).
    """
    try:
        return RunInfo.model_validate_json(read_regular_file(path / "run.json", MAX_RUN_JSON_BYTES))
    except ValidationError as exc:
        error = exc.errors()[0]
        where = ".".join(str(part) for part in error["loc"]) or "run.json"
        value = repr(error.get("input"))[:40]
        message = error["msg"].removeprefix("Value error, ")
        raise RunStoreError(
            f"{path / 'run.json'}: unreadable run record ({where}: {message}, got {value})"
        ) from None
    except (OSError, ValueError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise RunStoreError(f"{path / 'run.json'}: unreadable run record ({first})") from None


def read_run_record(path: Path) -> RunRecord:
    """The run in directory ``path``, its ``run.json`` read now (:func:`read_run_info`)."""
    return RunRecord(path.name, path, read_run_info(path))
