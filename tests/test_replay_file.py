"""A checkpoint's replay buffer holds only its filled rows and reads back equal, array for array."""

from __future__ import annotations

import pickle
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from gymnasium import spaces

from softtrack.rl.replay_file import load_replay_buffer, save_replay_buffer
from softtrack.rl.variants.per_arm import RewardShareReplayBuffer

OBS = spaces.Box(-1.0, 1.0, (81,), np.float32)
ACT = spaces.Box(-1.0, 1.0, (24,), np.float32)


class _Model(SimpleNamespace):
    """The one method of an off-policy model that loading uses (Stable-Baselines3's, abridged)."""

    def load_replay_buffer(self, path: Path) -> None:
        with path.open("rb") as file:
            self.replay_buffer = pickle.load(file)


def _filled(n: int, capacity: int = 500, n_envs: int = 2) -> RewardShareReplayBuffer:
    buffer = RewardShareReplayBuffer(capacity, OBS, ACT, "cpu", n_envs=n_envs)
    rng = np.random.default_rng(0)
    for _ in range(n):
        infos: list[dict[str, Any]] = [
            {"reward_shares": rng.normal(size=2).astype(np.float32)} for _ in range(n_envs)
        ]
        buffer.add(
            rng.normal(size=(n_envs, 81)).astype(np.float32),
            rng.normal(size=(n_envs, 81)).astype(np.float32),
            rng.uniform(-1, 1, (n_envs, 24)).astype(np.float32),
            rng.normal(size=n_envs).astype(np.float32),
            rng.random(n_envs) < 0.1,
            infos,
        )
    return buffer


def _arrays(buffer: Any) -> dict[str, np.ndarray]:
    return {k: v for k, v in vars(buffer).items() if isinstance(v, np.ndarray)}


@pytest.mark.parametrize("transitions", [0, 37, 250, 731])
def test_a_saved_buffer_reads_back_equal(tmp_path: Path, transitions: int) -> None:
    """Empty, partly filled, just full (250 rows of 2 envs) and wrapped buffers: every array
    (the reward shares included), the position and the full flag come back as they were."""
    buffer = _filled(transitions)
    save_replay_buffer(buffer, tmp_path / "replay_buffer.pkl")
    model = _Model()
    load_replay_buffer(model, tmp_path / "replay_buffer.pkl")
    loaded = model.replay_buffer
    assert isinstance(loaded, RewardShareReplayBuffer)
    assert (loaded.pos, loaded.full) == (buffer.pos, buffer.full)
    original = _arrays(buffer)
    assert set(_arrays(loaded)) == set(original)
    for name, value in original.items():
        np.testing.assert_array_equal(getattr(loaded, name), value, err_msg=name)
        assert getattr(loaded, name).dtype == value.dtype
    assert not hasattr(loaded, "_softtrack_cut_arrays")
    assert "reward_shares" in original


def test_a_partly_filled_buffer_writes_only_its_rows(tmp_path: Path) -> None:
    """50 of 500 rows (capacity 1000 transitions, 2 envs): the file is about a tenth of
    Stable-Baselines3's whole pickle, and the live buffer keeps its full-size arrays."""
    buffer = _filled(50, capacity=1000)
    save_replay_buffer(buffer, tmp_path / "cut.pkl")
    with (tmp_path / "whole.pkl").open("wb") as file:
        pickle.dump(buffer, file, protocol=pickle.HIGHEST_PROTOCOL)
    cut, whole = (tmp_path / "cut.pkl").stat().st_size, (tmp_path / "whole.pkl").stat().st_size
    assert cut < 0.15 * whole
    assert buffer.observations.shape == (500, 2, 81)
    assert not buffer.full and buffer.pos == 50


def test_a_stable_baselines3_pickle_still_loads(tmp_path: Path) -> None:
    """Checkpoints written before (the whole buffer, Stable-Baselines3's pickle) resume as before."""
    buffer = _filled(37)
    with (tmp_path / "old.pkl").open("wb") as file:
        pickle.dump(buffer, file, protocol=pickle.HIGHEST_PROTOCOL)
    model = _Model()
    load_replay_buffer(model, tmp_path / "old.pkl")
    np.testing.assert_array_equal(model.replay_buffer.observations, buffer.observations)
