"""Gymnasium tracking environments on the rod engine, single and batched.

``import softtrack.env`` registers ``softtrack/DualArmTracking-v0``,
``softtrack/SingleArmTracking-v0`` and ``softtrack/DualArmTransport-v0`` with Gymnasium.
"""

import gymnasium as gym

from softtrack.lazy import lazy_exports

__all__ = [
    "DualArmTrackingEnv",
    "DualArmTransportEnv",
    "NonFiniteActionError",
    "RewardConfig",
    "SingleArmTrackingEnv",
    "TargetConfig",
    "TrackingConfig",
    "TrackingCore",
    "make_config",
]

# imported at first use: the spec models import softtrack.env.targets, and the engine and
# environments behind these names (numba, SciPy's splines) would cost every command a second
_HOME = {
    "DualArmTrackingEnv": "softtrack.env.tracking_env",
    "DualArmTransportEnv": "softtrack.env.tracking_env",
    "NonFiniteActionError": "softtrack.env.core",
    "RewardConfig": "softtrack.env.reward",
    "SingleArmTrackingEnv": "softtrack.env.tracking_env",
    "TargetConfig": "softtrack.env.targets",
    "TrackingConfig": "softtrack.env.settings",
    "TrackingCore": "softtrack.env.core",
    "make_config": "softtrack.env.settings",
}

__getattr__, __dir__ = lazy_exports(__name__, _HOME, __all__)

for _name, _entry in (
    ("softtrack/DualArmTracking-v0", "softtrack.env.tracking_env:DualArmTrackingEnv"),
    ("softtrack/SingleArmTracking-v0", "softtrack.env.tracking_env:SingleArmTrackingEnv"),
    ("softtrack/DualArmTransport-v0", "softtrack.env.tracking_env:DualArmTransportEnv"),
):
    if _name not in gym.registry:
        gym.register(id=_name, entry_point=_entry, max_episode_steps=None)
