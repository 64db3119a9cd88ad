"""Rendering: the environments' rgb_array frames (Gymnasium's checker, RecordVideo), what a
frame shows (both arms, depth order, contact arrows), and the video files."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import imageio.v2 as imageio
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import softtrack.env  # noqa: F401  (registers the environments)
from softtrack.env.vec_env import TrackingVecEnv
from softtrack.report.video import VideoError, film_strip, write_video
from softtrack.viz.camera import FRONT
from softtrack.viz.scene import ARM_COLORS, SceneFrame, SceneRenderer
from softtrack.viz.scene_frames import closest_points, contact_arrows

ENV_IDS = [
    "softtrack/DualArmTracking-v0",
    "softtrack/SingleArmTracking-v0",
    "softtrack/DualArmTransport-v0",
]


def _colour_pixels(image: np.ndarray, colour: tuple[int, int, int], tolerance: int = 60) -> int:
    """Pixels whose hue is ``colour``'s (shaded: any brightness of it)."""
    pixels = image.reshape(-1, 3).astype(float)
    reference = np.asarray(colour, float)
    norm = np.linalg.norm(pixels, axis=1, keepdims=True) + 1e-9
    cosine = pixels @ reference / (norm[:, 0] * np.linalg.norm(reference))
    return int(((cosine > 0.985) & (norm[:, 0] > tolerance)).sum())


def _straight_rods(xs: tuple[float, ...] = (-0.1, 0.1), z: float = 0.0) -> np.ndarray:
    s = np.linspace(0.0, 1.0, 21)
    return np.stack([np.stack([np.full_like(s, x), s, np.full_like(s, z)]) for x in xs])


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_gymnasium_checker_passes_with_rgb_array(env_id: str) -> None:
    env = gym.make(env_id, render_mode="rgb_array").unwrapped
    check_env(env, skip_render_check=False)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (480, 640, 3) and frame.dtype == np.uint8
    assert env.metadata["render_fps"] == 500  # one frame per 2-ms control step: real time
    env.close()


def test_an_unknown_render_mode_is_one_clear_error() -> None:
    from softtrack.env.tracking_env import DualArmTrackingEnv

    with pytest.raises(ValueError, match="render_mode='rgb_array'"):
        DualArmTrackingEnv(render_mode="depth_array")
    with pytest.raises(ValueError, match="'rgb_array'"):
        TrackingVecEnv(1, render_mode="human")


def test_frames_show_both_arms_and_change_as_they_move() -> None:
    env = gym.make("softtrack/DualArmTracking-v0", render_mode="rgb_array", target="circle")
    env.reset(seed=0)
    first = env.render()
    for colour in ARM_COLORS:
        assert _colour_pixels(first, colour) > 500
    action = np.zeros(24, dtype=np.float32)
    action[:6] = 1.0
    for _ in range(100):
        env.step(action)
    assert np.abs(env.render().astype(int) - first.astype(int)).sum() > 10_000
    env.close()


def test_record_video_writes_a_playable_file(tmp_path: Path) -> None:
    env = gym.make("softtrack/DualArmTracking-v0", render_mode="rgb_array", episode_duration=0.1)
    env = gym.wrappers.RecordVideo(env, str(tmp_path), episode_trigger=lambda _: True, fps=25)
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        done = terminated or truncated
    env.close()
    videos = sorted(tmp_path.glob("*.mp4"))
    assert len(videos) == 1
    frames = imageio.mimread(videos[0], memtest=False)
    assert len(frames) == 51  # the reset's frame and one per step of 0.1 s / 2 ms
    assert frames[0].shape == (480, 640, 3)


def test_vec_env_draws_every_environment() -> None:
    vec = TrackingVecEnv(3, target="circle", render_mode="rgb_array")
    vec.reset()
    images = vec.get_images()
    assert len(images) == 3 and all(i is not None and i.shape == (480, 640, 3) for i in images)
    assert TrackingVecEnv(2, target="circle").get_images() == [None, None]


def test_a_nearer_rod_hides_the_farther_one() -> None:
    renderer = SceneRenderer(320, 240)
    back = _straight_rods((0.0,))[0]
    eye = np.asarray(FRONT.eye)[:, None]
    front = back + 0.3 * (eye - back)  # on the lines of sight to the back rod, nearer
    alone = renderer.render(
        SceneFrame(rods=back[None], radius=0.05, bases=back[None, :, 0], time=0.0)
    )
    both = renderer.render(
        SceneFrame(rods=np.stack([back, front]), radius=0.05, bases=back[None, :, 0], time=0.0)
    )
    seen_alone = _colour_pixels(alone, ARM_COLORS[0])
    assert seen_alone > 500
    assert _colour_pixels(both, ARM_COLORS[0]) < 0.1 * seen_alone
    assert _colour_pixels(both, ARM_COLORS[1]) > seen_alone


def test_contact_arrows_point_from_the_touch_along_the_force() -> None:
    rods = _straight_rods((-0.05, 0.05))
    on_a, on_b = closest_points(rods[0], rods[1])
    assert np.allclose(on_b - on_a, [0.1, 0.0, 0.0])
    arrows = contact_arrows(rods, 0.05, 12.0)
    assert len(arrows) == 2 and np.allclose(arrows[0][1], [12.0, 0.0, 0.0])
    sphere = np.array([0.0, 1.05, 0.0])
    held = contact_arrows(rods, 0.05, 0.0, sphere, 0.05, np.array([3.0, 0.0]))
    assert len(held) == 1 and held[0][1][1] > 0.0  # arm 1's tip pushes the sphere up and in
    plain = SceneRenderer(320, 240).render(
        SceneFrame(rods=rods, radius=0.05, bases=rods[:, :, 0], time=0.0)
    )
    with_arrows = SceneRenderer(320, 240).render(
        SceneFrame(rods=rods, radius=0.05, bases=rods[:, :, 0], time=0.0, contacts=arrows)
    )
    assert _colour_pixels(with_arrows, (250, 200, 20)) > _colour_pixels(plain, (250, 200, 20)) + 20


def test_the_camera_puts_the_workspace_in_the_frame() -> None:
    corners = np.array([[x, y, z] for x in (-0.6, 0.6) for y in (0.0, 1.1) for z in (-0.6, 0.6)])
    uvz = FRONT.project(corners, 640, 480)
    assert (uvz[:, 2] > 0).all()
    assert (uvz[:, 0] > -40).all() and (uvz[:, 0] < 680).all()
    assert (uvz[:, 1] > -40).all() and (uvz[:, 1] < 520).all()


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_videos_are_written_whole_or_not_at_all(tmp_path: Path, suffix: str) -> None:
    frames = [np.full((48, 64, 3), 20 * k, dtype=np.uint8) for k in range(6)]
    path = write_video(frames, tmp_path / f"clip{suffix}", fps=10)
    assert path.stat().st_size > 0
    assert len(imageio.mimread(path, memtest=False)) == 6
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"clip{suffix}"]


def test_bad_video_paths_are_refused_and_leave_nothing(tmp_path: Path) -> None:
    frames = [np.zeros((48, 64, 3), dtype=np.uint8)]
    with pytest.raises(VideoError, match=r"unknown animation format \.avi"):
        write_video(frames, tmp_path / "clip.avi", fps=10)
    with pytest.raises(VideoError, match="does not exist"):
        write_video(frames, tmp_path / "missing" / "clip.mp4", fps=10)
    with pytest.raises(VideoError, match="no frames"):
        write_video([], tmp_path / "clip.gif", fps=10)
    with pytest.raises(VideoError, match=r"an \.html page is written by softtrack animate"):
        write_video(frames, tmp_path / "clip.html", fps=10)
    with pytest.raises(VideoError, match="PNG"):
        film_strip(frames, tmp_path / "strip.jpg")
    assert list(tmp_path.iterdir()) == []
