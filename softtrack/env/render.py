"""An environment's state as a scene frame (``render_mode="rgb_array"``)."""

from __future__ import annotations

from softtrack.env.core import TrackingCore
from softtrack.viz.scene import SceneFrame
from softtrack.viz.scene_frames import scene_frame

__all__ = ["core_frame"]


def core_frame(core: TrackingCore, i: int = 0, label: str | None = None) -> SceneFrame:
    """Environment ``i`` of ``core`` now: the arms, clamps, target (transport: the sphere and
    its goal), contact forces and the errors."""
    config, engine = core.config, core.engine
    transport = core.transport
    sphere = None if transport is None else engine.sphere_position[i]
    return scene_frame(
        engine.position[i],
        float(config.sim.radius) * core.parameters(i)["radius_scale"],
        config.sim.base_positions,
        float(core.time[i]),
        engine.tip_position[i],
        core.targets.position[i] if transport is None else transport.goal_position[i],
        target_radius=float(config.target.sphere_radius),
        goal_offsets=core.goal_offsets,
        arm_numbers=None if config.arm is None else [config.arm],
        sphere=sphere,
        sphere_radius=0.05 if config.sim.sphere is None else float(config.sim.sphere.radius),
        contact_force=float(engine.contact_state()[1][i]) if engine.contact_on else 0.0,
        object_force=None if sphere is None else engine.sphere_contact_state()[0][i],
        label=label,
    )
