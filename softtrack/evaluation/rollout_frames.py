"""A recorded episode's instants as scene frames, for animations."""

from __future__ import annotations

from collections.abc import Iterator

from softtrack.env.settings import TrackingConfig
from softtrack.evaluation.episodes import Episode
from softtrack.viz.scene import SceneFrame
from softtrack.viz.scene_frames import scene_frame

__all__ = ["episode_frames"]


def episode_frames(
    episode: Episode, config: TrackingConfig, label: str | None = None
) -> Iterator[SceneFrame]:
    """A frame at each of the episode's snapshots (``Episode.snapshots``; for an animation,
    recorded at its frame rate: ``run_episodes(..., snapshot_every=k)``)."""
    if episode.snapshots is None or episode.snapshot_steps is None:
        return
    sphere_radius = 0.05 if config.sim.sphere is None else float(config.sim.sphere.radius)
    for nodes, step in zip(episode.snapshots, episode.snapshot_steps, strict=True):
        k = int(step)
        yield scene_frame(
            nodes,
            float(config.sim.radius),
            config.sim.base_positions,
            float(episode.t[k]),
            episode.tips[k],
            episode.target[k],
            target_radius=float(config.target.sphere_radius),
            goal_offsets=episode.goal_offsets,
            arm_numbers=None if config.arm is None else [config.arm],
            sphere=None if episode.object_position is None else episode.object_position[k],
            sphere_radius=sphere_radius,
            contact_force=0.0 if episode.contact_force is None else float(episode.contact_force[k]),
            object_force=None if episode.object_force is None else episode.object_force[k],
            label=label,
            path=episode.target,
        )
