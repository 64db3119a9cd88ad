"""The Optuna study of ``softtrack tune``: storage, slots, dead workers, status, best trial.

**The study** keeps, in its user attribute ``softtrack``, the tuned spec (fully resolved, with
its ``tune:`` section), its spec hash, the spec file and its ``base:`` chain; ``n_trials`` is
the number of finished trials asked for by the latest ``softtrack tune``. Workers read the
spec from the study, so every worker (on any host) tunes the same spec; continuing a study
with another spec or search space is an error.

**Slots keep the trial count exact.** The study holds ``n_trials`` slots. ``softtrack tune``
fills the free ones with *tickets* (Optuna ``WAITING`` trials, :func:`top_up`) before any
worker starts; a worker only ever takes a ticket (:func:`take_trial`: atomically ``WAITING``
→ ``RUNNING``) and never creates a trial, so however many workers pull from one study, no more
than ``n_trials`` trials finish. A finished trial (``COMPLETE`` or ``PRUNED``) keeps its slot;
a failed one frees it, and exactly one new ticket takes its place, added by whoever saw it
fail:

* interrupted (Ctrl-C, SIGTERM, a SLURM preemption): its worker adds a *retry* (the same
  values; the retry resumes the trial's run from its checkpoint);
* its worker died (SIGKILL, a lost node: the trial stays ``RUNNING``): the first worker or
  ``softtrack tune`` that notices adds a retry (at most :data:`MAX_DEATHS` per slot, then a
  fresh ticket). A dead worker is noticed by Optuna's heartbeat (every trial's heartbeat is
  recorded each :data:`HEARTBEAT_S` s; after :data:`GRACE_S` s without one the trial is
  failed) or, at once, by the run store: the trial's run is ``lost`` (nobody holds its
  ``run.lock`` and its heartbeat is stale or its process is gone on this host);
* training raised (or the trial's spec is invalid): its worker adds a fresh ticket (new
  values) and stops after :data:`MAX_ERRORS_IN_A_ROW` such trials in a row.

A trial's user attributes: ``run_id`` (its run), ``retry_of``/``replaces`` (the failed trial
it stands in for), ``deaths``, ``worker`` (host:pid), and for a failed one ``interrupted``,
``failure`` (worker died) or ``error`` (one line).

On SQLite, taking a ticket and failing dead trials happen under a file lock beside the
database (``optuna.db.lock``); other databases lock the trial's row. Run one ``softtrack tune``
per study at a time (it may run many workers): two at once can over-fill the slots.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import math
import os
import socket
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from softtrack.spec import ExperimentSpec, SpecError, load_spec, parse_spec, spec_hash, spec_to_yaml
from softtrack.spec.tune_models import TuneSpec, choice_key, trial_data
from softtrack.store.runs import RunStore, RunStoreError, pid_alive
from softtrack.store.status import is_lost
from softtrack.tune import TuneError

__all__ = [
    "DB_NAME",
    "GRACE_S",
    "HEARTBEAT_S",
    "MAX_DEATHS",
    "MAX_ERRORS_IN_A_ROW",
    "TuneStudy",
    "counts",
    "create_or_continue",
    "default_storage",
    "load_study",
    "shown_url",
    "take_trial",
    "top_up",
    "trial_name",
    "trial_spec",
]

DB_NAME = "optuna.db"
STUDY_ATTR = "softtrack"
HEARTBEAT_S = 10
"""A running trial's heartbeat is recorded this often, s."""
GRACE_S = 60
"""A running trial without a heartbeat for this long is failed (its worker died), s."""
MAX_DEATHS = 3
"""Retries of a slot whose workers died; then the slot gets a fresh ticket (new values)."""
MAX_ERRORS_IN_A_ROW = 3
"""A worker stops after this many trials in a row whose training raised."""


def optuna_module() -> Any:
    """``optuna``, imported quietly (warnings only), or a :class:`TuneError` saying how to
    install it."""
    try:
        import optuna
    except ImportError:
        raise TuneError(
            "softtrack tune needs optuna; install it with `pip install -c constraints.txt -e .`"
        ) from None
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    return optuna


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """Without Optuna's ExperimentalWarnings (heartbeat, constant liar, stale-trial checks)."""
    optuna = optuna_module()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        yield


def default_storage(runs_dir: str | os.PathLike[str]) -> str:
    """``sqlite:///<runs dir>/optuna.db`` (absolute), the default ``--storage``."""
    return "sqlite:///" + str((Path(runs_dir) / DB_NAME).resolve())


def shown_url(url: str) -> str:
    """``url`` with its password hidden."""
    try:
        from sqlalchemy.engine import make_url

        return str(make_url(url).render_as_string(hide_password=True))
    except Exception:
        return url


def _sqlite_file(url: str) -> Path | None:
    """The database file of a ``sqlite:///`` URL (``None`` for other databases)."""
    from sqlalchemy.engine import make_url

    try:
        parsed = make_url(url)
    except Exception:
        return None
    if parsed.get_backend_name() != "sqlite" or not parsed.database:
        return None
    return None if parsed.database == ":memory:" else Path(parsed.database)


def _open_storage(url: str, *, create: bool) -> Any:
    optuna = optuna_module()
    engine_kwargs: dict[str, Any] = {}
    db = _sqlite_file(url)
    if db is not None:
        if create:
            db.parent.mkdir(parents=True, exist_ok=True)
        elif not db.is_file():
            raise TuneError(
                f"{db}: no study database; start a study with `softtrack tune SPEC "
                "--trials N --study NAME` (or give its --storage / --runs-dir)"
            )
        engine_kwargs = {"connect_args": {"timeout": 60}}  # workers wait for each other's writes
    try:
        with _quiet():
            return optuna.storages.RDBStorage(
                url,
                engine_kwargs=engine_kwargs,
                heartbeat_interval=HEARTBEAT_S,
                grace_period=GRACE_S,
                heartbeat_stale_trial_callback=_replace_dead,
            )
    except Exception as exc:
        first = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise TuneError(
            f"--storage {shown_url(url)}: cannot open the study storage ({first}); give "
            "sqlite:///PATH, or a postgresql:// or mysql:// URL whose driver is installed"
        ) from None


# ------------------------------------------------------------------------------------------
# The study
# ------------------------------------------------------------------------------------------
_TUNE_FIELDS_ADDED_LATER = {"seeds_per_trial": 1, "aggregate": "mean"}


def _search_key(spec: ExperimentSpec) -> str:
    """What must stay the same when a study is continued: the spec hash (which the tune
    section leaves out) and the tune section."""
    assert spec.tune is not None
    data = spec.tune.model_dump(mode="json")
    for field, neutral in _TUNE_FIELDS_ADDED_LATER.items():  # studies made before keep theirs
        if data.get(field) == neutral:
            data.pop(field)
    tune = json.dumps(data, sort_keys=True)
    return hashlib.sha256(f"{spec_hash(spec)}|{tune}".encode()).hexdigest()


def make_pruner(tune: TuneSpec) -> Any:
    optuna = optuna_module()
    p = tune.pruner
    if p.type == "median":
        return optuna.pruners.MedianPruner(
            n_startup_trials=p.n_startup_trials, n_warmup_steps=p.n_warmup_steps
        )
    if p.type == "threshold":
        return optuna.pruners.ThresholdPruner(upper=p.upper, n_warmup_steps=p.n_warmup_steps)
    return optuna.pruners.NopPruner()


def make_sampler(tune: TuneSpec, number: int) -> Any:
    """TPE seeded by ``tune.seed`` and the trial number: a trial's draw does not depend on
    which worker draws it or how often workers started, and parallel workers never share a
    random stream (``constant_liar`` keeps them off each other's running trials)."""
    import numpy as np

    optuna = optuna_module()
    seed = int(np.random.SeedSequence([int(tune.seed), int(number)]).generate_state(1)[0])
    with _quiet():
        return optuna.samplers.TPESampler(
            seed=seed, n_startup_trials=tune.n_startup_trials, constant_liar=True
        )


@dataclass
class TuneStudy:
    """An opened study: the Optuna study, its storage and the spec it tunes.

    Attributes:
        study: the ``optuna.Study``.
        storage: its ``optuna.storages.RDBStorage``.
        url: the storage URL.
        name: the study name.
        spec: the tuned spec (with ``tune``).
        info: the study's ``softtrack`` attribute (spec data, spec files, hashes).
    """

    study: Any
    storage: Any
    url: str
    name: str
    spec: ExperimentSpec
    info: dict[str, Any]

    @property
    def tune(self) -> TuneSpec:
        assert self.spec.tune is not None
        return self.spec.tune

    @property
    def n_trials(self) -> int:
        """Finished trials asked for by the latest ``softtrack tune`` (0: never set)."""
        return int(self.study.user_attrs.get("n_trials", 0))

    @property
    def spec_files(self) -> list[str]:
        return list(self.info.get("spec_files") or [])

    def trials(self, *states: str) -> list[Any]:
        """Its trials (``FrozenTrial``), by number; only those in ``states`` (names such as
        ``"WAITING"``) if given."""
        optuna = optuna_module()
        chosen = tuple(optuna.trial.TrialState[s] for s in states) if states else None
        return list(self.study.get_trials(deepcopy=False, states=chosen))

    def trial_id(self, number: int) -> int:
        study_id = self.storage.get_study_id_from_name(self.name)
        return int(self.storage.get_trial_id_from_study_id_trial_number(study_id, number))

    @contextlib.contextmanager
    def lock(self) -> Iterator[None]:
        """Exclusive access to the slots (a file lock beside a SQLite database; other
        databases lock the rows themselves)."""
        db = _sqlite_file(self.url)
        if db is None:
            yield
            return
        fd = os.open(f"{db}.lock", os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            yield
        finally:
            os.close(fd)


def create_or_continue(
    url: str, name: str, spec: ExperimentSpec, spec_files: Sequence[str], spec_file: str | None
) -> TuneStudy:
    """Open study ``name`` (creating it, and the SQLite file, if needed) for ``spec``.

    Raises:
        TuneError: the study exists for another spec or search space, or was not made by
            ``softtrack tune``; the storage cannot be opened.
    """
    optuna = optuna_module()
    assert spec.tune is not None
    storage = _open_storage(url, create=True)
    info = {
        "spec": spec.model_dump(mode="json"),
        "spec_hash": spec_hash(spec),
        "search_key": _search_key(spec),
        "spec_files": list(spec_files),
        "spec_file": spec_file,
    }
    with _quiet():
        study = optuna.create_study(
            study_name=name,
            storage=storage,
            direction="minimize",
            load_if_exists=True,
            pruner=make_pruner(spec.tune),
            sampler=make_sampler(spec.tune, 0),
        )
    existing = study.user_attrs.get(STUDY_ATTR)
    if existing is None:
        if study.trials:
            raise TuneError(
                f"study {name!r} in {shown_url(url)} was not made by softtrack tune; "
                "name another study with --study"
            )
        study.set_user_attr(STUDY_ATTR, info)
        existing = info
    elif existing.get("search_key") != info["search_key"]:
        was = (existing.get("spec_files") or ["another spec"])[0]
        raise TuneError(
            f"study {name!r} tunes another spec or search space (it was started from {was}); "
            "continue it with the same spec, tune: section and --set options, or name a new "
            "study with --study"
        )
    return TuneStudy(study, storage, url, name, spec, dict(existing))


def load_study(url: str, name: str) -> TuneStudy:
    """Open the existing study ``name`` (its spec from the study itself).

    Raises:
        TuneError: no such study (the names there are listed), or not a softtrack study.
        SpecError: its stored spec no longer validates.
    """
    optuna = optuna_module()
    storage = _open_storage(url, create=False)
    try:
        with _quiet():
            study = optuna.load_study(study_name=name, storage=storage)
    except KeyError:
        names = optuna.study.get_all_study_names(storage)
        there = ", ".join(names) if names else "none"
        raise TuneError(
            f"no study {name!r} in {shown_url(url)} (studies there: {there}); "
            "start it with `softtrack tune SPEC --trials N --study NAME`"
        ) from None
    info = study.user_attrs.get(STUDY_ATTR)
    if not isinstance(info, dict) or "spec" not in info:
        raise TuneError(f"study {name!r} in {shown_url(url)} was not made by softtrack tune")
    spec = parse_spec(info["spec"], source=f"study {name}")
    if spec.tune is None:
        raise TuneError(f"study {name!r}: its stored spec has no tune: section")
    study.pruner = make_pruner(spec.tune)
    return TuneStudy(study, storage, url, name, spec, dict(info))


# ------------------------------------------------------------------------------------------
# A trial's values and spec
# ------------------------------------------------------------------------------------------
def trial_name(name: str, number: int) -> str:
    """The experiment name of trial ``number``'s run: ``<name>-t<number>`` (≤ 64 chars)."""
    suffix = f"-t{int(number)}"
    return name[: 64 - len(suffix)].rstrip("._-") + suffix


def suggest(trial: Any, tune: TuneSpec) -> dict[str, Any]:
    """Draw (or, for a retry, take the fixed) value of every param: ``{path: spec value}``."""
    values: dict[str, Any] = {}
    for path, p in tune.params.items():
        if p.type == "float":
            assert p.low is not None and p.high is not None
            values[path] = trial.suggest_float(path, p.low, p.high, log=p.log, step=p.step)
        elif p.type == "int":
            assert p.low is not None and p.high is not None
            values[path] = trial.suggest_int(
                path, int(p.low), int(p.high), log=p.log, step=int(p.step or 1)
            )
        else:
            choices = list(p.choices or [])
            keys = [choice_key(c) for c in choices]
            values[path] = choices[keys.index(trial.suggest_categorical(path, keys))]
    return values


def decode_params(tune: TuneSpec, params: dict[str, Any]) -> dict[str, Any]:
    """A trial's stored params (Optuna's values) as spec values (categorical choices back
    from their JSON text)."""
    values: dict[str, Any] = {}
    for path, p in tune.params.items():
        if path not in params:
            continue
        value = params[path]
        if p.type == "categorical":
            choices = list(p.choices or [])
            keys = [choice_key(c) for c in choices]
            value = choices[keys.index(value)] if value in keys else value
        elif p.type == "int":
            value = int(value)
        values[path] = value
    return values


def trial_spec(ts: TuneStudy, values: dict[str, Any], name: str) -> ExperimentSpec:
    """The run spec of a trial: the tuned spec without ``tune``, with ``values`` set, named
    ``name``, and its first seed only (validated: raises :class:`SpecError`)."""
    data = trial_data(ts.spec.model_dump(mode="json", exclude={"tune"}), values)
    data["name"] = name
    data["seeds"] = [int(ts.spec.seeds[0])]
    data.pop("tune", None)
    shown = ", ".join(f"{k}={json.dumps(v)}" for k, v in values.items())
    return parse_spec(data, source=f"study {ts.name} ({shown})")


# ------------------------------------------------------------------------------------------
# Slots
# ------------------------------------------------------------------------------------------
def counts(trials: Sequence[Any]) -> dict[str, int]:
    """Trials per state (``complete``, ``pruned``, ``running``, ``waiting``, ``fail``) and
    ``finished`` (complete + pruned)."""
    out = {"complete": 0, "pruned": 0, "running": 0, "waiting": 0, "fail": 0}
    for t in trials:
        out[t.state.name.lower()] = out.get(t.state.name.lower(), 0) + 1
    out["finished"] = out["complete"] + out["pruned"]
    return out


def _attrs(**values: Any) -> dict[str, Any]:
    return {k: v for k, v in values.items() if v is not None}


def run_attr(index: int) -> str:
    """The trial user attribute naming its run of seed index ``index``: ``run_id`` for the
    first (as a one-seed trial's), ``run_id_1``, ``run_id_2``, … for the others."""
    return "run_id" if index == 0 else f"run_id_{index}"


def trial_runs(trial: Any) -> dict[str, str]:
    """The trial's run ids by user attribute (:func:`run_attr`)."""
    return {
        key: str(value)
        for key, value in trial.user_attrs.items()
        if (key == "run_id" or key.startswith("run_id_")) and value
    }


def enqueue_retry(study: Any, trial: Any, *, died: bool) -> None:
    """Put a ticket for failed ``trial``'s slot: the same values and run (a retry), or a fresh
    ticket once its workers died :data:`MAX_DEATHS` times or when the trial died before all
    its values were drawn (a retry would draw the missing ones anew, and its values would no
    longer be those of the run)."""
    deaths = int(trial.user_attrs.get("deaths", 0)) + int(died)
    tuned = (study.user_attrs.get(STUDY_ATTR) or {}).get("spec", {}).get("tune") or {}
    complete = set(tuned.get("params", {})) <= set(trial.params)
    if deaths > MAX_DEATHS or not complete:
        study.enqueue_trial({}, user_attrs={"replaces": trial.number})
        return
    study.enqueue_trial(
        dict(trial.params),
        user_attrs=_attrs(retry_of=trial.number, deaths=deaths or None, **trial_runs(trial)),
    )


def enqueue_fresh(study: Any, replaces: int | None = None) -> None:
    """Put a fresh ticket (values drawn when a worker takes it)."""
    study.enqueue_trial({}, user_attrs=_attrs(replaces=replaces))


def _replace_dead(study: Any, trial: Any) -> None:
    """Optuna's callback for a trial it failed for a stale heartbeat."""
    enqueue_retry(study, trial, died=True)


def _worker_alive(worker: str) -> bool:
    """Whether a trial's ``worker`` (``host:pid``) is a live process on this host (a retry's
    run still looks lost between the moment a worker takes the ticket and the moment it
    locks the run; only the worker's own death makes the trial lost)."""
    host, _, pid = worker.rpartition(":")
    return host == socket.gethostname() and pid.isdigit() and pid_alive(int(pid))


def _fail_lost_trials(ts: TuneStudy, store: RunStore) -> None:
    """Fail the running trials whose worker died, each replaced by a retry: by Optuna's
    heartbeat, and by their run being ``lost`` in the store."""
    optuna = optuna_module()
    with _quiet():
        optuna.storages.fail_stale_trials(ts.study)
    for t in ts.trials("RUNNING"):
        if _worker_alive(str(t.user_attrs.get("worker", ""))):
            continue
        lost_runs = []
        for run_id in trial_runs(t).values():
            try:
                if is_lost(store.get_run(run_id)):
                    lost_runs.append(run_id)
            except RunStoreError:
                continue
        if not lost_runs:
            continue
        run_id = lost_runs[0]
        trial_id = ts.trial_id(t.number)
        try:
            ts.storage.set_trial_user_attr(
                trial_id, "failure", f"its worker died (run {run_id} lost)"
            )
            if not ts.storage.set_trial_state_values(trial_id, optuna.trial.TrialState.FAIL):
                continue
        except optuna.exceptions.UpdateFinishedTrialError:
            continue
        enqueue_retry(ts.study, ts.storage.get_trial(trial_id), died=True)


def top_up(ts: TuneStudy, store: RunStore, n_trials: int) -> int:
    """Set the study's ``n_trials`` and fill its free slots; returns the tickets added.

    First the trials of dead workers are failed (and retried); then every failed trial
    without a stand-in gets one, while slots are free: a retry (its run resumes) unless its
    training raised; the remaining free slots get fresh tickets.
    """
    with ts.lock():
        ts.study.set_user_attr("n_trials", int(n_trials))
        _fail_lost_trials(ts, store)
        trials = ts.trials()
        c = counts(trials)
        free = int(n_trials) - (c["finished"] + c["running"] + c["waiting"])
        covered = {t.user_attrs.get(k) for t in trials for k in ("retry_of", "replaces")}
        added = 0
        for t in trials:
            if free <= 0:
                break
            if t.state.name != "FAIL" or t.number in covered:
                continue
            if "error" in t.user_attrs:
                enqueue_fresh(ts.study, replaces=t.number)
            else:
                enqueue_retry(ts.study, t, died="failure" in t.user_attrs)
            free -= 1
            added += 1
        for _ in range(max(free, 0)):
            enqueue_fresh(ts.study)
            added += 1
        return added


def take_trial(ts: TuneStudy, store: RunStore) -> Any | None:
    """A ticket of the study as an ``optuna.Trial`` now ``RUNNING`` in this process (retries
    first), or ``None`` if none is left (or ``n_trials`` trials are finished or running)."""
    optuna = optuna_module()
    with ts.lock():
        _fail_lost_trials(ts, store)
        trials = ts.trials()
        c = counts(trials)
        if ts.n_trials and c["finished"] + c["running"] >= ts.n_trials:
            return None
        waiting = [t for t in trials if t.state.name == "WAITING"]
        waiting.sort(key=lambda t: ("retry_of" not in t.user_attrs, t.number))
        for t in waiting:
            trial_id = ts.trial_id(t.number)
            try:
                if not ts.storage.set_trial_state_values(trial_id, optuna.trial.TrialState.RUNNING):
                    continue
            except optuna.exceptions.UpdateFinishedTrialError:
                continue
            ts.storage.record_heartbeat(trial_id)
            ts.storage.set_trial_user_attr(
                trial_id, "worker", f"{socket.gethostname()}:{os.getpid()}"
            )
            ts.study.sampler = make_sampler(ts.tune, t.number)
            with _quiet():
                return optuna.trial.Trial(ts.study, trial_id)
    return None


# ------------------------------------------------------------------------------------------
# Status and the best trial
# ------------------------------------------------------------------------------------------
def _short(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _param_labels(paths: Sequence[str]) -> dict[str, str]:
    """Each path's last part, or the whole path where two paths share it."""
    leaves = [p.rsplit(".", 1)[-1] for p in paths]
    return {
        p: (leaf if leaves.count(leaf) == 1 else p) for p, leaf in zip(paths, leaves, strict=True)
    }


def best_trial(ts: TuneStudy) -> Any | None:
    """The complete trial with the lowest score (``None`` before the first one)."""
    complete = [t for t in ts.trials("COMPLETE") if t.value is not None]
    return min(complete, key=lambda t: (t.value, t.number)) if complete else None


def summary_line(ts: TuneStudy) -> str:
    """``study td3-tune: 7/10 finished (5 complete, 2 pruned), 1 running, 2 waiting, 1 failed;
    best trial 3: 0.0412 m``."""
    c = counts(ts.trials())
    n = ts.n_trials
    text = (
        f"study {ts.name}: {c['finished']}/{n} finished ({c['complete']} complete, "
        f"{c['pruned']} pruned), {c['running']} running, {c['waiting']} waiting, "
        f"{c['fail']} failed"
    )
    best = best_trial(ts)
    if best is not None:
        text += f"; best trial {best.number}: {best.value:.4g} m"
    return text


def _training_note(store: RunStore | None, run_id: object) -> str | None:
    """``training at step 85,872 of 1,500,000`` from a running trial's run record (its last
    heartbeat), ``None`` without a store or a readable record."""
    if store is None or not run_id:
        return None
    try:
        info = store.get_run(str(run_id)).info
    except RunStoreError:
        return None
    return f"training at step {info.global_step:,} of {info.total_timesteps:,}"


def status_rows(ts: TuneStudy, store: RunStore | None = None) -> list[dict[str, Any]]:
    """One row per trial: number, state, value (m), step (the last reported), params (spec
    values), run_id, note (retry of / pruned at / failure / retried as; with the runs'
    ``store``, a running trial's training step)."""
    rows = []
    trials = ts.trials()
    retried_as = {t.user_attrs["retry_of"]: t.number for t in trials if "retry_of" in t.user_attrs}
    for t in trials:
        attrs = t.user_attrs
        notes = []
        if "retry_of" in attrs:
            notes.append(f"retry of {attrs['retry_of']}")
        if "replaces" in attrs:
            notes.append(f"replaces {attrs['replaces']}")
        if t.state.name == "PRUNED" and t.intermediate_values:
            notes.append(f"pruned at step {max(t.intermediate_values):,}")
        if t.state.name == "RUNNING":
            notes.append(_training_note(store, attrs.get("run_id")) or "")
        reasons = [str(attrs[key]) for key in ("interrupted", "failure", "error") if key in attrs]
        if t.state.name == "FAIL" and not reasons:
            reasons.append("its worker stopped (no heartbeat)")
        notes.extend(reasons)
        if t.state.name == "FAIL" and t.number in retried_as:
            notes.append(f"retried as {retried_as[t.number]}")
        value = t.value
        if value is None and t.intermediate_values:
            value = t.intermediate_values[max(t.intermediate_values)]
        rows.append(
            {
                "number": t.number,
                "state": t.state.name,
                "value": None if value is None or not math.isfinite(value) else float(value),
                "step": max(t.intermediate_values) if t.intermediate_values else None,
                "params": decode_params(ts.tune, t.params),
                "run_id": attrs.get("run_id"),
                "note": "; ".join(n for n in notes if n),
            }
        )
    return rows


def format_status(ts: TuneStudy, store: RunStore | None = None) -> str:
    """The summary line and a table of the trials (``softtrack tune --status``); with the
    runs' ``store``, how far each running trial's training has got."""
    rows = status_rows(ts, store)
    labels = _param_labels(list(ts.tune.params))
    header = ["trial", "state", "score_m", "step", "run_id", "params", "note"]
    lines = [
        [
            str(r["number"]),
            r["state"].lower(),
            "" if r["value"] is None else f"{r['value']:.4f}",
            "" if r["step"] is None else f"{r['step']:,}",
            r["run_id"] or "",
            " ".join(f"{labels[p]}={_short(v).replace(' ', '')}" for p, v in r["params"].items()),
            r["note"],
        ]
        for r in rows
    ]
    widths = [max(len(x) for x in col) for col in zip(header, *lines, strict=True)]
    out = [summary_line(ts), f"storage {shown_url(ts.url)}"]
    if lines:
        out.append("  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)).rstrip())
        out += [
            "  ".join(c.ljust(w) for c, w in zip(line, widths, strict=True)).rstrip()
            for line in lines
        ]
    return "\n".join(out)


def best_spec_text(ts: TuneStudy, out: Path, runs_dir: str | os.PathLike[str] | None) -> str:
    """The best trial as a spec file's text to be written at ``out``: ``base:`` the tuned spec
    file (relative to ``out``'s directory), ``name`` the trial run's experiment name (so the
    spec has the run's hash), ``tune: null`` and every value that differs from the base file
    (the best values and the tuning's ``--set`` overrides), after a comment naming the study,
    trial, score and run. Where the tuned spec file is gone (or the difference would not give
    the run's spec), the whole resolved spec instead.

    Raises:
        TuneError: no complete trial yet.
    """
    import yaml

    best = best_trial(ts)
    if best is None:
        raise TuneError(
            f"study {ts.name!r} has no complete trial yet; see `softtrack tune --status {ts.name}`"
        )
    run_id = best.user_attrs.get("run_id")
    name = trial_name(ts.spec.name, best.number)
    if run_id and runs_dir is not None:
        with contextlib.suppress(RunStoreError):
            name = RunStore(runs_dir).get_run(str(run_id)).info.name
    values = decode_params(ts.tune, best.params)
    spec = trial_spec(ts, values, name)
    shown = ", ".join(f"{p} = {json.dumps(v)}" for p, v in values.items())
    retry_of = best.user_attrs.get("retry_of")
    trial = f"trial {best.number}" + (
        f" (a retry of trial {retry_of})" if retry_of is not None else ""
    )
    header = (
        f"# Best trial of study {ts.name} (softtrack tune, {ts.n_trials} "
        f"trial{'' if ts.n_trials == 1 else 's'}): {trial}, "
        f"run {run_id or '?'},\n"
        f"# validation score {best.value:.6g} m (mean 3-D RMSE at its best checkpoint)\n"
        f"# storage: {_portable_url(ts.url)}\n# values: {shown}\n"
        "# Train it with `softtrack train THIS_FILE`: its runs join the trial's run (same "
        "experiment\n# name and spec hash).\n"
    )
    for base_file in _base_candidates(ts.info.get("spec_file"), out):
        try:
            base = load_spec(base_file)
            exclude = {"tune", "name", "seeds"}
            diff = _diff(
                base.model_dump(mode="json", exclude=exclude),
                spec.model_dump(mode="json", exclude=exclude),
            )
            relative = os.path.relpath(os.path.abspath(base_file), os.path.abspath(out.parent))
            doc: dict[str, Any] = {"base": relative, "name": name, "tune": None, **diff}
            text = header + yaml.safe_dump(
                doc, sort_keys=False, default_flow_style=None, width=100, allow_unicode=True
            )
            if _hash_of_text(text, out) == spec_hash(spec):
                return text
        except SpecError:
            pass
    full = spec.model_copy(update={"seeds": list(ts.spec.seeds)})
    return (
        header
        + "# (the whole resolved spec: the tuned spec file is not available)\n"
        + spec_to_yaml(full)
    )


def _base_candidates(spec_file: str | None, out: Path) -> list[Path]:
    """Files the best spec may name as its ``base:``, in order: the tuned spec's namesake
    beside ``out`` (the same file in this checkout when the study was started from another
    one, so that the written spec stays valid in a clone), then the file the study was started
    from. Only existing files."""
    if not spec_file:
        return []
    started_from = Path(spec_file)
    candidates = [out.parent / started_from.name, started_from]
    unique = {os.path.abspath(c): c for c in candidates if c.is_file()}
    return list(unique.values())


def _portable_url(url: str) -> str:
    """``url`` as the header of a written spec shows it: a SQLite file below the working
    directory relative to it (no machine path in a committed file), else :func:`shown_url`."""
    db = _sqlite_file(url)
    if db is not None and db.is_absolute():
        with contextlib.suppress(ValueError):
            return f"sqlite:///{db.relative_to(Path.cwd()).as_posix()}"
    return shown_url(url)


def _diff(old: dict[str, Any], new: dict[str, Any]) -> dict[str, Any]:
    """The entries of ``new`` that differ from ``old`` (mappings compared key by key)."""
    out: dict[str, Any] = {}
    for key, value in new.items():
        if key in old and old[key] == value:
            continue
        if isinstance(value, dict) and isinstance(old.get(key), dict):
            sub = _diff(old[key], value)
            if sub:
                out[key] = sub
        else:
            out[key] = value
    return out


def _hash_of_text(text: str, out: Path) -> str | None:
    """The spec hash of ``text`` if it were the file ``out`` (its base resolved from there)."""
    import tempfile

    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile(
        "w", suffix=".yaml", dir=out.parent, delete=False, encoding="utf-8"
    ) as fh:
        fh.write(text)
    try:
        return spec_hash(load_spec(fh.name))
    except SpecError:
        return None
    finally:
        os.unlink(fh.name)
