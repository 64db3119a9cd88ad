"""``softtrack animate``: a run's evaluation replayed and drawn, as a video, GIF, HTML player
or film strip.

The rods' nodes are not stored at every step, so the run's deterministic policy is replayed
on the trajectory with the nodes kept at the animation's frame rate; the replay's tips are
then compared with the run's stored ``eval_trajectories`` (float32, to the last bit on the
CPU that evaluated it), and any difference is reported, never hidden. Nothing is written into
the run: a shipped run animates read-only.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from softtrack.evaluation.episodes import Episode, run_episode
from softtrack.evaluation.rollout_frames import episode_frames
from softtrack.evaluation.run_evaluation import RANDOM_TARGET_SEED, PolicyLoader
from softtrack.report.video import VideoError, film_strip, video_format, write_page, write_video
from softtrack.report.viewer import Rollout, viewer_page
from softtrack.spec.env_config import env_config
from softtrack.store.provenance import cpu_kind
from softtrack.store.runs import RunRecord, RunStoreError
from softtrack.store.tables import TableError, read_table
from softtrack.viz.scene import SceneRenderer

__all__ = ["Replay", "animate_runs", "replay_run", "rollout_of"]

#: Frames of a film strip, evenly spaced over the episode, the last at its end.
STRIP_FRAMES = 6


@dataclass(frozen=True)
class Replay:
    """One run's episode, replayed with the arms' nodes at the animation's frames.

    Attributes:
        record: the run.
        episode: the replayed episode (``snapshots``: the frames' nodes).
        check: one line on how the replay's tips compare with the stored evaluation.
        matches: whether they are equal to the last stored bit (``None``: nothing stored).
        random: the held-out random-target episode replayed, if that.
    """

    record: RunRecord
    episode: Episode
    check: str
    matches: bool | None
    random: int | None = None


def frame_steps(duration: float, control_dt: float, fps: float) -> np.ndarray:
    """(F,) the 0-based control steps after which frames are taken at ``fps`` over
    ``duration`` s (the first after 1/fps s, the last at the end)."""
    n_steps = round(duration / control_dt)
    n_frames = max(1, round(duration * fps))
    times = np.arange(1, n_frames + 1) / fps
    return np.unique(np.clip(np.round(times / control_dt).astype(int) - 1, 0, n_steps - 1))


def replay_run(
    record: RunRecord, trajectory: str, fps: float, load: PolicyLoader, random: int | None = None
) -> Replay:
    """Replay ``record``'s policy on ``trajectory`` (or, with ``random`` = k, the k-th
    held-out random-target episode of ``softtrack evaluate --random``) with the nodes kept
    at ``fps``.

    Raises:
        RunStoreError: no readable model.
    """
    spec = record.load_spec()
    config = env_config(spec)
    duration = float(spec.training.eval_duration)
    policy = load(record, spec, "policy")
    steps = frame_steps(duration, config.sim.control_dt, fps).tolist()
    if random is not None:
        seed = RANDOM_TARGET_SEED + int(random)
        episode = run_episode(policy, config, "random", duration, seed, snapshot_steps=steps)
        note = (
            f"{record.info.name}: random-target episode {random} (seed {seed}); "
            "eval_random keeps no path to compare the replay with"
        )
        return Replay(record, episode, note, None, int(random))
    episode = run_episode(policy, config, trajectory, duration, snapshot_steps=steps)
    check, matches = _compare_with_stored(record, trajectory, episode)
    return Replay(record, episode, check, matches)


def _compare_with_stored(
    record: RunRecord, trajectory: str, episode: Episode
) -> tuple[str, bool | None]:
    path = record.table_path("eval_trajectories")
    name = record.info.name
    if not path.is_file():
        return f"{name}: no stored evaluation to compare the replay with", None
    try:
        table = read_table(path, ["trajectory", "step", "arm", "tip_x", "tip_y", "tip_z"])
    except TableError as exc:
        return f"{name}: the stored evaluation is unreadable ({exc}); replay not compared", None
    rows = table[table["trajectory"] == trajectory].sort_values(["step", "arm"])
    if rows.empty:
        return f"{name}: no stored {trajectory} evaluation to compare the replay with", None
    n_arms = episode.tips.shape[1]
    stored = rows[["tip_x", "tip_y", "tip_z"]].to_numpy(np.float32).reshape(-1, n_arms, 3)
    replayed = episode.tips.astype(np.float32)
    if stored.shape != replayed.shape:
        return (
            f"{name}: the replay ran {len(replayed)} steps, the stored evaluation {len(stored)}",
            False,
        )
    if np.array_equal(stored, replayed, equal_nan=True):
        return f"{name}: the replay's tips equal the stored evaluation's to the last bit", True
    worst = float(np.nanmax(np.abs(stored.astype(np.float64) - replayed)))
    here, there = cpu_kind(), _evaluation_cpu(record, trajectory)
    if there is not None and there != here:
        why = (
            f"the stored evaluation ran on {there}, this replay on {here}: the closed loop "
            "amplifies last-bit differences between CPU kinds (docs/performance.md)"
        )
    else:
        why = "on this CPU kind: the code or the model changed since; `softtrack evaluate RUN` renews it"
    return (
        f"{name}: the replay's tips differ from the stored evaluation by up to {worst:.2e} m; {why}",
        False,
    )


def _evaluation_cpu(record: RunRecord, trajectory: str) -> str | None:
    """The CPU kind the run's stored ``trajectory`` evaluation ran on (eval_metrics.cpu)."""
    try:
        metrics = read_table(record.table_path("eval_metrics"), ["trajectory", "cpu"])
    except (TableError, KeyError, ValueError):
        return None
    kinds = metrics.loc[metrics["trajectory"] == trajectory, "cpu"].dropna().unique()
    return str(kinds[0]) if len(kinds) else None


def animate_runs(
    records: Sequence[RunRecord],
    trajectories: Sequence[str],
    out: str | os.PathLike[str],
    *,
    load: PolicyLoader,
    fps: float = 30.0,
    size: tuple[int, int] = (640, 480),
    strip: str | os.PathLike[str] | None = None,
    labels: Sequence[str] | None = None,
    random: int | None = None,
    on_note: Callable[[str], None] | None = None,
) -> Path:
    """Replay and draw ``records`` on ``trajectories`` (``random``: the k-th held-out random
    target instead) into ``out``: an MP4 or GIF of one trajectory with the runs side by side
    (one panel each, the same target), or an HTML page that plays every run on every
    trajectory in 3-D (:mod:`softtrack.report.viewer`); with ``strip``, also a PNG film strip
    of :data:`STRIP_FRAMES` instants of the first trajectory.

    Raises:
        VideoError: bad ``out``/``strip``, no encoder, several trajectories for a video
            (checked before any replay); RunStoreError: a run without a readable model.
    """
    suffix = video_format(out)
    if strip is not None and Path(strip).suffix.lower() != ".png":
        raise VideoError(f"{strip}: a film strip is a PNG; name it *.png")
    for path in (out, strip):
        if path is not None:
            _make_parent(Path(path))
    if suffix != ".html" and len(trajectories) != 1:
        raise VideoError(f"{out}: a video shows one trajectory; choose one, or write an .html page")
    if not records:
        raise RunStoreError("animate: no run given; name a run id, a run directory or a name")
    names = list(labels or [_label(record) for record in records])
    replays = {
        (name, trajectory): replay_run(record, trajectory, fps, load, random)
        for record, name in zip(records, names, strict=True)
        for trajectory in trajectories
    }
    for replay in replays.values():
        if on_note is not None:
            on_note(replay.check)
    if suffix == ".html":
        rollouts = [rollout_of(name, replay) for (name, _), replay in replays.items()]
        page = viewer_page(rollouts, " vs ".join(names), fps)
        written = write_page(page, out)
    width, height = (max(2, int(v) - int(v) % 2) for v in size)  # H.264: even sizes
    renderer = SceneRenderer(width, height)
    first = trajectories[0]
    streams = [
        list(
            episode_frames(
                replays[name, first].episode,
                env_config(replays[name, first].record.load_spec()),
                name,
            )
        )
        for name in names
    ]
    n_frames = min(len(frames) for frames in streams)

    def panels(k: int) -> np.ndarray:
        return np.concatenate([renderer.render(frames[k]) for frames in streams], axis=1)

    if suffix != ".html":
        written = write_video((panels(k) for k in range(n_frames)), out, fps)
    if strip is not None:
        picks = np.linspace(0, n_frames - 1, STRIP_FRAMES).round().astype(int)
        film_strip([panels(int(k)) for k in picks], strip, columns=3 if len(streams) == 1 else 1)
    return written


def rollout_of(name: str, replay: Replay) -> Rollout:
    """The viewer's rollout of one replay (its frames: the episode's snapshots)."""
    episode, config = replay.episode, env_config(replay.record.load_spec())
    assert episode.snapshots is not None and episode.snapshot_steps is not None
    steps = episode.snapshot_steps
    if episode.object_position is not None:
        sphere = episode.object_position[steps]
        errors = np.linalg.norm(sphere - episode.target[steps], axis=-1)[:, None]
    else:
        sphere = None
        goals = episode.target[steps][:, None, :]
        if episode.goal_offsets is not None:
            goals = goals + episode.goal_offsets[None]
        errors = np.linalg.norm(episode.tips[steps] - goals, axis=-1)
    return Rollout(
        controller=name,
        trajectory=episode.trajectory if replay.random is None else f"random {replay.random}",
        times=episode.t[steps],
        nodes=episode.snapshots,
        target=episode.target[steps],
        sphere=sphere,
        errors=errors,
        radius=float(config.sim.radius),
        target_radius=float(config.target.sphere_radius),
        sphere_radius=0.05 if config.sim.sphere is None else float(config.sim.sphere.radius),
        bases=np.asarray(config.sim.base_positions, float)[: episode.snapshots.shape[1]],
    )


def _make_parent(path: Path) -> None:
    """Create the directory ``path`` goes into (an output path under a file: one line)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise VideoError(
            f"{path}: its directory cannot be created ({exc.strerror or exc}); choose another --out"
        ) from None


def _label(record: RunRecord) -> str:
    info = record.info
    return f"{info.name} (seed {info.seed})"
