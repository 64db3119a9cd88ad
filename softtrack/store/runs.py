"""Run directories and their ``run.json``.

A :class:`RunStore` is a directory (``runs/`` by default, see :func:`resolve_runs_dir`) with
one sub-directory per run, named by its ULID (:mod:`softtrack.store.ids`). A run directory is
created atomically, then ``spec.yaml`` and finally ``run.json`` are written (atomically); a
directory without ``run.json`` is an aborted creation and is ignored by :meth:`RunStore.list_runs`.

``run.json`` (:class:`RunInfo`) holds the status (queued → running → completed | failed |
interrupted), ISO-8601 UTC times (created, started, ended, heartbeat), the seed, the spec
hash, the git commit and dirty flag of the code, library versions, the command line, the
progress (global_step, steps_per_second) and the CPU of the running process. It has a single
writer at a time (the process that runs the run); every update is an atomic read-modify-write
of the whole file.
"""

from __future__ import annotations

import os
import shutil
import socket
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Literal

from softtrack.env.tasks import N_ARMS
from softtrack.spec import (
    ExperimentSpec,
    chain_comment,
    spec_hash,
    spec_to_yaml,
)
from softtrack.store.atomic import atomic_write_text, is_temp_file
from softtrack.store.catalog import note_run, read_catalog
from softtrack.store.disk import FULL_ERRNOS
from softtrack.store.errors import RunStoreError
from softtrack.store.ids import create_unique_dir, is_valid_id
from softtrack.store.liveness import lock_file_held, pid_alive
from softtrack.store.location import RUNS_DIR_ENV, resolve_runs_dir
from softtrack.store.provenance import (
    cpu_description,
    git_info,
    library_versions,
    portable_command,
    portable_path,
)
from softtrack.store.run_records import (
    RUN_STATUSES,
    RunInfo,
    RunRecord,
    RunStatus,
    UnreadableRun,
    iso_value,
    read_run_info,
    utc_now,
)

__all__ = [
    "RUNS_DIR_ENV",
    "RUN_STATUSES",
    "RunInfo",
    "RunLockedError",
    "RunNotFoundError",
    "RunRecord",
    "RunStatus",
    "RunStore",
    "RunStoreError",
    "UnreadableRun",
    "git_info",
    "library_versions",
    "lock_held",
    "pid_alive",
    "resolve_runs_dir",
    "run_lock",
    "utc_now",
]


class RunNotFoundError(RunStoreError, LookupError):
    """No run (or no unique run) matches the given id."""


_UPDATABLE = frozenset(RunInfo.model_fields) - {"format_version", "run_id", "created"}


class RunStore:
    """The runs under one directory.

    Args:
        root: the runs directory (created on the first :meth:`create_run`).
    """

    def __init__(self, root: str | os.PathLike[str]) -> None:
        self.root = Path(root)

    def __repr__(self) -> str:
        return f"RunStore({str(self.root)!r})"

    # ---- creation ----------------------------------------------------------------------
    def create_run(
        self,
        spec: ExperimentSpec,
        seed: int,
        command: list[str] | None = None,
        *,
        status: RunStatus = "queued",
        notes: dict[str, Any] | None = None,
        spec_files: Sequence[str | os.PathLike[str]] = (),
    ) -> RunRecord:
        """Create a run directory with ``spec.yaml`` (``spec`` with ``seeds: [seed]``) and
        ``run.json``. The directory name is a fresh ULID obtained with an atomic ``mkdir``.

        Args:
            spec: the validated experiment spec.
            seed: this run's seed (normally one of ``spec.seeds``).
            command: the command line to record (default ``sys.argv``), recorded as
                :func:`~softtrack.store.provenance.portable_command` gives it (program
                ``softtrack``, no absolute paths).
            status: initial status.
            notes: free-form additions to run.json (e.g. the sweep that created the run).
            spec_files: the spec file and its ``base:`` chain
                (:func:`softtrack.spec.spec_chain`), named in comments at the top of the run's
                ``spec.yaml``; the spec itself is written fully resolved, so it loads on its own.
        """
        run_spec = spec.with_seed(seed)
        budget = int(spec.training.total_timesteps)  # per policy
        independent = spec.controller == "independent"
        run_id, path = create_unique_dir(self.root)
        try:
            header = f"# fully resolved spec of run {run_id} (seed {int(seed)})\n"
            header += chain_comment([portable_path(f) for f in spec_files])
            atomic_write_text(path / "spec.yaml", header + spec_to_yaml(run_spec))
            (path / "tables").mkdir()
            (path / "checkpoints").mkdir()
            commit, dirty = git_info()
            info = RunInfo(
                run_id=run_id,
                name=spec.name,
                algo=spec.mpc.method if spec.controller == "mpc" else spec.algo.name,
                controller=spec.controller,
                seed=int(seed),
                status=status,
                created=utc_now(),
                total_timesteps=N_ARMS * budget if independent else budget,
                arm_total_timesteps=budget if independent else None,
                arm_steps=[0] * N_ARMS if independent else None,
                spec_hash=spec_hash(spec),
                git_commit=commit,
                git_dirty=dirty,
                versions=library_versions(),
                command=portable_command(list(sys.argv if command is None else command)),
                host=socket.gethostname(),
                cpu=cpu_description(),
                notes=dict(notes or {}),
            )
            self._write(path, info)  # last: a directory with run.json is a complete run
        except BaseException:
            shutil.rmtree(path, ignore_errors=True)
            raise
        return RunRecord(run_id, path, info)

    # ---- lookup ------------------------------------------------------------------------
    def _resolve(self, run_id: str) -> Path:
        if not self.root.is_dir():
            raise RunNotFoundError(
                f"{self.root}: no runs directory, so no run {run_id!r}; "
                "pass --runs-dir or set SOFTTRACK_RUNS_DIR to the directory holding the runs"
            )
        run_id = run_id.strip().rstrip("/").split("/")[-1]
        exact = self.root / run_id
        if run_id and (exact / "run.json").is_file():
            return exact
        key = run_id.upper()
        # a prefix selects by run id only: a directory named otherwise (models/<name>) is
        # matched by its whole name, so `td3-sbx-64` is never a run of `td3-sbx-64-tuned`
        matches = [
            p
            for p in self.root.iterdir()
            if key and is_valid_id(p.name) and p.name.startswith(key) and (p / "run.json").is_file()
        ]
        if not matches and key:  # a directory named otherwise (models/<name>): its run.json id
            columns = read_catalog(self.root).columns(["dir", "run_id"])
            matches = [
                self.root / directory
                for directory, found in zip(columns["dir"], columns["run_id"], strict=True)
                if found is not None and found.upper().startswith(key)
            ]
        if len(matches) == 1:
            return matches[0]
        if not matches and run_id and exact.is_dir() and (exact / "spec.yaml").is_file():
            raise RunStoreError(
                f"{exact / 'run.json'}: the run record is missing, so run {run_id} cannot be "
                f"used; {UnreadableRun(exact, '').fix}"
            )
        hint = f"list the runs with `softtrack runs --runs-dir {self.root}`"
        if len(matches) > 1:
            raise RunNotFoundError(
                f"{self.root}: {run_id!r} matches {len(matches)} runs; give more characters of "
                f"the id ({hint})"
            )
        raise RunNotFoundError(f"{self.root}: no run {run_id!r}; {hint}")

    def _write(self, path: Path, info: RunInfo) -> None:
        self._write_run_json(path, info)
        note_run(path)

    def _write_run_json(self, path: Path, info: RunInfo) -> None:
        text = info.model_dump_json(indent=2) + "\n"
        try:
            atomic_write_text(path / "run.json", text)
        except OSError as exc:
            if exc.errno not in FULL_ERRNOS or not (path / "run.json").is_file():
                raise
            # a full disk has no room for the new copy, but rewriting the old file in place
            # reuses its blocks: the run's status is worth that small risk
            with open(path / "run.json", "r+b") as fh:
                fh.write(text.encode("utf-8"))
                fh.truncate()
                fh.flush()
                os.fsync(fh.fileno())

    def read_record(self, path: Path) -> RunRecord:
        """The run in directory ``path``, its ``run.json`` read now.

        Raises:
            RunStoreError: ``run.json`` is missing or unreadable.
        """
        return RunRecord(path.name, path, read_run_info(path))

    def get_run(self, run_id: str) -> RunRecord:
        """The run with this id, or with a unique id prefix (case-insensitive).

        Raises:
            RunNotFoundError: no such run, or the prefix is ambiguous.
            RunStoreError: its run.json is unreadable.
        """
        path = self._resolve(run_id)
        return RunRecord(path.name, path, read_run_info(path))

    def list_runs(self) -> list[RunRecord]:
        """All complete runs, oldest first. Unreadable or unfinished directories are skipped
        (:meth:`list_unreadable` names them)."""
        return [item for item in self._scan() if isinstance(item, RunRecord)]

    def list_unreadable(self) -> list[UnreadableRun]:
        """Directories that hold a run (a ``spec.yaml`` or a ``run.json``) whose ``run.json`` is
        missing or unreadable, with the reason, by name."""
        return [item for item in self._scan() if isinstance(item, UnreadableRun)]

    def _scan(self) -> list[RunRecord | UnreadableRun]:
        if not self.root.is_dir():
            return []
        found: list[RunRecord | UnreadableRun] = []
        for path in sorted(self.root.iterdir()):
            if not path.is_dir() or is_temp_file(path):
                continue
            if not (path / "run.json").is_file():
                if (path / "spec.yaml").is_file():
                    found.append(UnreadableRun(path, "run.json is missing"))
                continue
            try:
                found.append(RunRecord(path.name, path, read_run_info(path)))
            except RunStoreError as exc:
                found.append(UnreadableRun(path, str(exc).split(": ", 1)[-1]))
        return found

    # ---- updates -----------------------------------------------------------------------
    def update_run(self, run_id: str, **fields: Any) -> RunRecord:
        """Atomically read, update and rewrite ``run.json``; returns the new record.

        ``datetime`` values are stored as ISO 8601 UTC. Keys must be :class:`RunInfo`
        fields (put free-form data under ``notes``).

        Raises:
            TypeError: an unknown or read-only field.
            pydantic.ValidationError: a value of the wrong type (e.g. an unknown status).
        """
        bad = sorted(set(fields) - _UPDATABLE)
        if bad:
            raise TypeError(
                f"cannot update run.json field(s) {bad}; updatable: {sorted(_UPDATABLE)}"
            )
        path = self._resolve(run_id)
        data = read_run_info(path).model_dump()
        data.update({key: iso_value(value) for key, value in fields.items()})
        info = RunInfo.model_validate(data)
        self._write(path, info)
        return RunRecord(path.name, path, info)

    def mark_running(self, run_id: str) -> RunRecord:
        """status=running, heartbeat=now (and started, the first time), this host and pid,
        error cleared, and a new entry in ``sessions`` (call it with the run's lock held). An
        open last session (its process died unrecorded) is closed as ``lost`` at the larger of
        run.json's step and the steps its checkpoints saved (:meth:`RunRecord.saved_steps`)."""
        now = utc_now()
        record = self.get_run(run_id)
        info = record.info
        sessions = _close_last_session(  # open: its process died unrecorded
            info.sessions,
            ended=info.heartbeat,
            end_step=max(info.global_step, record.saved_steps()),
            status="lost",
        )
        commit, dirty = git_info()
        session = {
            "started": now,
            "host": socket.gethostname(),
            "cpu": cpu_description(),
            "pid": os.getpid(),
            "git_commit": commit,
            "git_dirty": dirty,
        }
        return self.update_run(
            run_id,
            status="running",
            started=info.started or now,
            heartbeat=now,
            ended=None,
            error=None,
            traceback=None,
            host=session["host"],
            cpu=session["cpu"],
            pid=session["pid"],
            sessions=[*sessions, session],
        )

    def heartbeat(
        self,
        run_id: str,
        global_step: int,
        steps_per_second: float | None = None,
        **extra: Any,
    ) -> RunRecord:
        """Record progress (and any other ``extra`` fields) and the time of this sign of life."""
        fields: dict[str, Any] = {
            **extra,
            "heartbeat": utc_now(),
            "global_step": int(global_step),
        }
        if steps_per_second is not None:
            fields["steps_per_second"] = float(steps_per_second)
        return self.update_run(run_id, **fields)

    def mark_finished(
        self,
        run_id: str,
        status: Literal["completed", "failed", "interrupted"],
        *,
        error: str | None = None,
        **fields: Any,
    ) -> RunRecord:
        """Final status, ended=now, an optional one-line error, and any other fields."""
        now = utc_now()
        if error is not None:
            error = " ".join(str(error).split())
        info = self.get_run(run_id).info
        sessions = _close_last_session(
            info.sessions,
            ended=now,
            end_step=int(fields.get("global_step", info.global_step)),
            status=status,
            steps_per_second=fields.get("steps_per_second", info.steps_per_second),
        )
        return self.update_run(
            run_id,
            status=status,
            ended=now,
            heartbeat=now,
            error=error,
            sessions=sessions,
            **fields,
        )


def _close_last_session(sessions: list[dict[str, Any]], **end: Any) -> list[dict[str, Any]]:
    """``sessions`` with ``end`` added to the last one if it is still open (no ``ended``)."""
    if sessions and "ended" not in sessions[-1]:
        return [*sessions[:-1], {**sessions[-1], **end}]
    return sessions


# ---- liveness -------------------------------------------------------------------------------
class RunLockedError(RunStoreError):
    """Another process holds the run's lock: it is training the run right now."""


#: Lock files this process holds (resolved paths): a command that holds a run's lock may call
#: another that takes it (an flock is per open file, so the second open would refuse itself).
_HELD_LOCKS: set[Path] = set()


@contextmanager
def run_lock(record: RunRecord, activity: str = "trained") -> Iterator[None]:
    """Hold ``run.lock`` (an exclusive, non-blocking ``flock``) while the body runs.

    Training, evaluation that writes into the run and export each hold it, so none of them
    reads or writes a run while another process changes it. The kernel releases the lock when
    the process dies, even by SIGKILL, so a held lock means a live process is using the run;
    its holder writes one line into the file (pid, host, ``activity``) for the error of the
    next one. Re-entrant within one process.

    Raises:
        RunLockedError: another process holds the lock.
    """
    import fcntl

    path = record.lock_path.resolve()
    if path in _HELD_LOCKS:
        yield
        return
    fd = os.open(record.lock_path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise RunLockedError(
                f"run {record.run_id} is {_lock_holder(fd, record)}; wait for it or stop it first"
            ) from None
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()} {socket.gethostname()} {activity}\n".encode())
        _HELD_LOCKS.add(path)
        try:
            yield
        finally:
            _HELD_LOCKS.discard(path)
    finally:
        os.close(fd)  # releases the lock


def _lock_holder(fd: int, record: RunRecord) -> str:
    """What the lock's holder wrote (``being <activity> by another process (pid …)``), or
    the training process of run.json for a lock file written before holders wrote one."""
    try:
        pid, host, activity = os.pread(fd, 200, 0).decode("utf-8").split(maxsplit=2)
        int(pid)
    except (OSError, UnicodeDecodeError, ValueError):
        pid, host, activity = str(record.info.pid), str(record.info.host), "trained"
    return f"being {activity.strip()} by another process (pid {pid} on {host})"


def lock_held(record: RunRecord) -> bool | None:
    """Whether some process holds the run's lock (``None``: the run has no lock file)."""
    return lock_file_held(record.lock_path)
