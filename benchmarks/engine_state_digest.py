"""A digest of the engine's state after 150 control steps of three scenes, to check that a
change of the kernels keeps their arithmetic bit for bit.

The scenes of ``bench_engine.py`` on a batch of 5 environments, each with its own actuation
scale: random actions with gravity (the contact-free kernel), the arms pressed together with
rod–rod contact, and the sphere held with contact and gravity. Prints one SHA-256 per scene
over every state array (and the contact outputs); run it before and after a change, on the
same machine:

    git checkout <commit before> -- softtrack/sim  # or a second checkout of it
    .venv/bin/python benchmarks/engine_state_digest.py > before.txt; git checkout HEAD -- softtrack/sim
    .venv/bin/python benchmarks/engine_state_digest.py | diff before.txt -

The digests differ between CPU kinds (fused multiply-adds), never between two runs on one.
"""

from __future__ import annotations

import hashlib

import numpy as np
from bench_engine import holding_torques, scene_torques

from softtrack.sim import RodBatch, SimParams
from softtrack.sim.params import CONTACT_ON
from softtrack.sim.sphere import SphereParams

N_ENVS = 5
CONTROL_STEPS = 150


def scene_digest(params: SimParams, torques: np.ndarray) -> str:
    """SHA-256 of the batch's state (and contact outputs) after :data:`CONTROL_STEPS` control
    steps of ``torques`` ((50, A, 2, N) N·m, cycled; scaled 0.6–1.2 across the batch)."""
    batch = RodBatch(N_ENVS, params)
    tiled = np.broadcast_to(torques[:, None], (len(torques), N_ENVS, *torques.shape[1:])).copy()
    tiled *= np.linspace(0.6, 1.2, N_ENVS)[None, :, None, None, None]
    for k in range(CONTROL_STEPS):
        batch.set_element_torques(tiled[k % len(tiled)])
        batch.advance()
    digest = hashlib.sha256()
    for value in vars(batch.get_state()).values():
        if value is not None:
            digest.update(np.ascontiguousarray(value).tobytes())
    if params.contact_k:
        for value in batch.contact_state():
            if value is not None:
                digest.update(np.ascontiguousarray(value).tobytes())
    return digest.hexdigest()


def main() -> None:
    free = SimParams()
    scenes = {
        "random actions, gravity": (
            SimParams(gravity=9.81),
            scene_torques("random", free, np.random.default_rng(1)),
        ),
        "pressed, rod-rod contact": (
            SimParams(**CONTACT_ON),
            scene_torques("pressed", free, np.random.default_rng(2)),
        ),
        "sphere held, contact, gravity": (
            SimParams(**CONTACT_ON, gravity=9.81, sphere=SphereParams()),
            holding_torques(free),
        ),
    }
    for name, (params, torques) in scenes.items():
        print(f"{name:30} {scene_digest(params, torques)}")


if __name__ == "__main__":
    main()
