"""The renderer against the simulation it draws, side by side in one process on one core.

Steps each environment (``DualArmTracking-v0`` on the circle; ``DualArmTransport-v0`` with
its sphere and contact) with a fixed smooth action for one 10-s episode, keeping a frame's
state every 1/30 s, then times (median of ``--repeats``):

* the simulation's control steps per second (``env.step``, no rendering);
* the renderer's frames per second at 640×480 (``render_mode="rgb_array"``: the arms'
  tubes, clamps, target, sphere, contact arrows and text, returned as an array);
* what a 10-s episode costs: simulating its 5,000 control steps at 2 ms, and drawing its
  300 frames at 30 fps.

Run on one core:

    taskset -c 0 .venv/bin/python benchmarks/bench_render.py
"""

from __future__ import annotations

import argparse
import statistics
import time

import gymnasium as gym
import numpy as np

import softtrack.env  # noqa: F401  (registers the environments)
from softtrack.env.render import core_frame
from softtrack.viz.scene import SceneRenderer

FPS = 30.0


def _action(k: int, size: int) -> np.ndarray:
    phase = 2.0 * np.pi * k / 1500.0
    return (0.6 * np.sin(phase + np.arange(size))).astype(np.float32)


def bench(env_id: str, repeats: int) -> list[str]:
    env = gym.make(env_id, target="circle", render_mode="rgb_array").unwrapped
    env.reset(seed=0)
    steps = env.config.max_episode_steps
    every = max(1, round(1.0 / FPS / env.config.sim.control_dt))
    frames = []
    started = time.perf_counter()
    for k in range(steps):
        env.step(_action(k, env.action_space.shape[0]))
        if (k + 1) % every == 0:
            frames.append(core_frame(env.core, 0))
    step_rate = steps / (time.perf_counter() - started)
    renderer = SceneRenderer(640, 480)
    renderer.render(frames[0])  # compiles (numba, cached) and draws the background once
    rates = []
    for _ in range(repeats):
        started = time.perf_counter()
        for frame in frames:
            renderer.render(frame)
        rates.append(len(frames) / (time.perf_counter() - started))
    frame_rate = statistics.median(rates)
    simulate_s, draw_s = steps / step_rate, len(frames) / frame_rate
    env.close()
    return [
        f"| {env_id} | {step_rate:,.0f} | {frame_rate:,.0f} | {simulate_s:.2f} | "
        f"{len(frames)} frames: {draw_s:.2f} | {draw_s / simulate_s:.2f} |"
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    lines = [
        "| environment | simulation: control steps/s | renderer: frames/s (640×480) "
        "| simulate 10 s (s) | draw 10 s at 30 fps (s) | draw / simulate |",
        "|---|---|---|---|---|---|",
    ]
    for env_id in ("softtrack/DualArmTracking-v0", "softtrack/DualArmTransport-v0"):
        lines += bench(env_id, args.repeats)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
