"""Gymnasium tracking environments on the rod engine, single and batched.

``import softtrack.env`` registers ``softtrack/DualArmTracking-v0``,
``softtrack/SingleArmTracking-v0`` and ``softtrack/DualArmTransport-v0`` with Gymnasium.
"""

import gymnasium as gym

from softtrack.env.config import TrackingConfig, make_config
from softtrack.env.core import NonFiniteActionError, TrackingCore
from softtrack.env.reward import RewardConfig
from softtrack.env.targets import TargetConfig
from softtrack.env.tracking_env import (
    DualArmTrackingEnv,
    DualArmTransportEnv,
    SingleArmTrackingEnv,
)

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

for _name, _entry in (
    ("softtrack/DualArmTracking-v0", "softtrack.env.tracking_env:DualArmTrackingEnv"),
    ("softtrack/SingleArmTracking-v0", "softtrack.env.tracking_env:SingleArmTrackingEnv"),
    ("softtrack/DualArmTransport-v0", "softtrack.env.tracking_env:DualArmTransportEnv"),
):
    if _name not in gym.registry:
        gym.register(id=_name, entry_point=_entry, max_episode_steps=None)
