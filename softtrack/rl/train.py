"""Train one run of the store, from scratch or resumed from its latest checkpoint.

:func:`train_run` owns the run while it trains: it marks it ``running``, logs episodes and
checkpoints through :mod:`softtrack.rl.callbacks`, and ends it as

* ``completed``: the budget is done; ``model.zip`` (and ``vecnormalize.pkl``) saved;
* ``interrupted``: SIGINT or SIGTERM arrived; the current step finished, a checkpoint was
  saved and the pending episodes written (exit code 128 + signal: 130 for SIGINT);
* ``failed``: an exception; its traceback (one line) is in run.json's ``error``.

Resuming loads the newest checkpoint that loads (falling back to older ones if it is
corrupt), restores the step count, replay buffer and normalisation statistics, drops rows
of ``train_episodes`` written after that checkpoint (so a resumed run has no duplicate or
missing episode numbers) and continues to ``training.total_timesteps``. A run killed with
SIGKILL (status still ``running``) resumes the same way.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import threading
import traceback
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from softtrack.rl.callbacks import (
    Checkpointer,
    EpisodeLogger,
    ProgressMonitor,
    TrainingClock,
    save_checkpoint,
)
from softtrack.rl.factory import build_model, check_supported, load_model, make_vec_env
from softtrack.spec import ExperimentSpec
from softtrack.store.atomic import atomic_path, remove_temp_files
from softtrack.store.runs import RunRecord, RunStore, RunStoreError
from softtrack.store.tables import read_table, write_table

__all__ = ["TrainOutcome", "check_resumable", "train_run"]


@dataclass(frozen=True)
class TrainOutcome:
    """How a call of :func:`train_run` ended.

    Attributes:
        run_id: the run.
        status: ``completed``, ``interrupted`` or ``failed``.
        global_step: env steps done (over all sessions).
        steps_per_second: throughput of this session, env steps/s.
        exit_code: 0, 128 + signal number, or 1 (failed).
        error: one-line error of a failed run.
    """

    run_id: str
    status: str
    global_step: int
    steps_per_second: float | None
    exit_code: int
    error: str | None = None


class _StopFlag:
    def __init__(self) -> None:
        self.signum: int | None = None

    def __call__(self) -> bool:
        return self.signum is not None


@contextmanager
def _signals_to(flag: _StopFlag) -> Iterator[None]:
    """SIGINT/SIGTERM set ``flag`` (a second SIGINT raises KeyboardInterrupt)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, _frame: Any) -> None:
        if flag.signum is not None and signum == signal.SIGINT:
            raise KeyboardInterrupt
        flag.signum = signum

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def _load_state(checkpoint: Path) -> dict[str, Any]:
    state = json.loads((checkpoint / "state.json").read_text(encoding="utf-8"))
    if not isinstance(state, dict) or "global_step" not in state:
        raise ValueError(f"{checkpoint / 'state.json'}: no global_step")
    return state


def _restore(
    spec: ExperimentSpec, record: RunRecord, seed: int
) -> tuple[Any, Any, dict[str, Any]] | None:
    """(model, env, state) from the newest loadable checkpoint, or None if there is none."""
    from stable_baselines3.common.vec_env import VecNormalize

    for checkpoint in reversed(record.list_checkpoints()):
        env = None
        try:
            state = _load_state(checkpoint)
            env = make_vec_env(spec, seed + int(state["global_step"]), normalize=False)
            if spec.algo.normalize:
                env = VecNormalize.load(str(checkpoint / "vecnormalize.pkl"), env)
            model = load_model(spec, checkpoint / "model.zip", env)
            buffer = checkpoint / "replay_buffer.pkl"
            if spec.algo.is_off_policy and buffer.exists():
                model.load_replay_buffer(buffer)
            if int(model.num_timesteps) != int(state["global_step"]):
                raise ValueError("model and state.json disagree on the step count")
            return model, env, state
        except Exception:  # noqa: BLE001 (a corrupt checkpoint: fall back to the previous one)
            if env is not None:
                env.close()
            continue
    return None


def _truncate_episodes(record: RunRecord, global_step: int, episodes: int | None) -> int:
    """Keep the episodes written up to ``global_step`` (and below index ``episodes``);
    returns how many remain (= the next episode index)."""
    path = record.table_path("train_episodes")
    if not path.exists():
        return 0
    df = read_table(path)
    keep = df["global_step"] <= global_step
    if episodes is not None:
        keep &= df["episode"] < episodes
    kept = df[keep].sort_values("episode").reset_index(drop=True)
    if len(kept) != len(df):
        write_table(path, kept)
    return len(kept)


def _save_final(model: Any, record: RunRecord) -> None:
    with atomic_path(record.model_path) as tmp:
        model.save(tmp)
    vec_normalize = model.get_vec_normalize_env()
    if vec_normalize is not None:
        with atomic_path(record.path / "vecnormalize.pkl") as tmp:
            vec_normalize.save(str(tmp))


def check_resumable(record: RunRecord) -> None:
    """Raise :class:`RunStoreError` if ``record`` is completed or still running here."""
    info = record.info
    if info.status == "completed":
        raise RunStoreError(
            f"run {record.run_id} is already completed; start a new run with `softtrack train SPEC`"
        )
    if info.status == "running" and info.pid and info.pid != os.getpid():
        import socket

        if info.host == socket.gethostname():
            try:
                os.kill(info.pid, 0)
            except ProcessLookupError:
                return
            except PermissionError:
                pass
            raise RunStoreError(
                f"run {record.run_id} is still running (pid {info.pid}); stop it first "
                "(Ctrl-C or kill -TERM) and resume it then"
            )


def train_run(
    store: RunStore, record: RunRecord, *, resume: bool = False, show_progress: bool | None = None
) -> TrainOutcome:
    """Train ``record`` to its budget; see the module docstring for the statuses.

    Args:
        store: the run store holding ``record``.
        record: the run (its ``spec.yaml`` defines everything).
        resume: continue from the latest checkpoint (the run must not be completed).
        show_progress: force the progress bar on/off (default: on a terminal without ``CI``).

    Raises:
        SpecError: the run's spec is invalid or not supported.
        RunStoreError: the run cannot be resumed (completed, or still running).
    """
    spec = record.load_spec()
    check_supported(spec, str(record.spec_path))
    if resume:
        check_resumable(record)
        remove_temp_files(record.path)
    seed = int(record.info.seed)
    total = int(spec.training.total_timesteps)
    flag = _StopFlag()
    model: Any = None
    env: Any = None
    episodes: EpisodeLogger | None = None
    monitor: ProgressMonitor | None = None
    clock = TrainingClock()
    store.mark_running(record.run_id)
    try:
        with _signals_to(flag):
            restored = _restore(spec, record, seed) if resume else None
            if restored is not None:
                model, env, state = restored
                step = int(model.num_timesteps)
                next_episode = _truncate_episodes(record, step, state.get("episodes"))
                clock = TrainingClock(float(state.get("wall_time", 0.0)))
                model.set_random_seed(seed + step)
            else:
                if resume:  # nothing to resume from: start over, cleanly
                    record.table_path("train_episodes").unlink(missing_ok=True)
                    for old in record.list_checkpoints():
                        shutil.rmtree(old, ignore_errors=True)
                env = make_vec_env(spec, seed)
                model = build_model(spec, env, seed)
                next_episode = 0
            episodes = EpisodeLogger(record, clock, next_episode)
            checkpointer = Checkpointer(
                record,
                episodes,
                clock,
                spec.training.checkpoint_interval,
                spec.training.keep_checkpoints,
                spec.training.save_replay_buffer,
            )
            monitor = ProgressMonitor(
                store,
                record,
                episodes,
                total,
                spec.training.heartbeat_interval,
                flag,
                show=show_progress,
            )
            from stable_baselines3.common.callbacks import CallbackList

            remaining = total - int(model.num_timesteps)
            if remaining > 0 and not flag():
                model.learn(
                    total_timesteps=remaining if restored is not None else total,
                    callback=CallbackList([episodes, checkpointer, monitor]),
                    reset_num_timesteps=restored is None,
                    progress_bar=False,
                )
            monitor.close()
            sps = monitor.steps_per_second()
            step = int(model.num_timesteps)
            if flag.signum is not None:
                save_checkpoint(
                    model,
                    record,
                    episodes,
                    clock,
                    save_replay_buffer=spec.training.save_replay_buffer,
                    keep=spec.training.keep_checkpoints,
                )
                fields: dict[str, Any] = {"global_step": step}
                if sps is not None:
                    fields["steps_per_second"] = sps
                store.mark_finished(record.run_id, "interrupted", **fields)
                return TrainOutcome(record.run_id, "interrupted", step, sps, 128 + flag.signum)
            episodes.flush()
            _save_final(model, record)
            fields = {"global_step": step}
            if sps is not None:
                fields["steps_per_second"] = sps
            store.mark_finished(record.run_id, "completed", **fields)
            return TrainOutcome(record.run_id, "completed", step, sps, 0)
    except KeyboardInterrupt:  # a second Ctrl-C: stop now, without a checkpoint
        _finish_abruptly(store, record, episodes, model, monitor, "interrupted", None)
        raise
    except Exception as exc:  # noqa: BLE001 (recorded in run.json as a failed run)
        text = "".join(traceback.format_exception(exc))
        _finish_abruptly(store, record, episodes, model, monitor, "failed", text)
        step = int(model.num_timesteps) if model is not None else record.info.global_step
        line = f"{type(exc).__name__}: {exc}"
        return TrainOutcome(record.run_id, "failed", step, None, 1, " ".join(line.split()))
    finally:
        if env is not None:
            env.close()


def _finish_abruptly(
    store: RunStore,
    record: RunRecord,
    episodes: EpisodeLogger | None,
    model: Any,
    monitor: ProgressMonitor | None,
    status: Any,
    error: str | None,
) -> None:
    if monitor is not None:
        with contextlib.suppress(Exception):
            monitor.close()
    if episodes is not None:
        with contextlib.suppress(Exception):  # keep what can be kept; the status matters more
            episodes.flush()
    fields: dict[str, Any] = {}
    if model is not None:
        fields["global_step"] = int(model.num_timesteps)
    store.mark_finished(record.run_id, status, error=error, **fields)
