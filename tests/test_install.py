"""softtrack as a user installs it: a wheel, used outside the checkout. The wheel's package
(not this checkout) runs `softtrack quickstart` and evaluates a shipped policy; the checkout's
files stay untouched."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

CHECKOUT = Path(__file__).resolve().parents[1]
TINY = [
    "--set",
    "training.total_timesteps=200",
    "--set",
    "training.n_envs=2",
    "--set",
    "training.checkpoint_interval=0",
    "--set",
    "training.eval_duration=0.2",
    "--set",
    "env.episode_duration=0.1",
    "--set",
    "algo.learning_starts=50",
    "--set",
    "algo.batch_size=16",
    "--set",
    "algo.buffer_size=2000",
]


@pytest.fixture(scope="module")
def wheel_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The softtrack wheel built from this checkout, installed (without dependencies: this
    environment has them) into a directory of its own."""
    tmp = tmp_path_factory.mktemp("wheel")
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "-q",
            "--no-deps",
            "--no-build-isolation",
            "-w",
            str(tmp / "dist"),
            str(CHECKOUT),
        ],
        check=True,
        capture_output=True,
    )
    (wheel,) = (tmp / "dist").glob("softtrack-*.whl")
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "-q",
            "--no-deps",
            "--target",
            str(tmp / "site"),
            str(wheel),
        ],
        check=True,
        capture_output=True,
    )
    return tmp / "site"


def _softtrack(site: Path, cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    code = (
        "import sys, softtrack; print('package:', softtrack.__file__, file=sys.stderr); "
        "from softtrack.cli import app; sys.argv = ['softtrack', *sys.argv[1:]]; app()"
    )
    env = {**os.environ, "PYTHONPATH": str(site), "CI": "1"}
    return subprocess.run(
        [sys.executable, "-c", code, *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_the_wheel_runs_quickstart_and_a_shipped_policy_outside_the_checkout(
    wheel_site: Path, tmp_path: Path
) -> None:
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    result = _softtrack(
        wheel_site, elsewhere, "quickstart", *TINY, "--runs-dir", "runs", "--out", "report"
    )
    assert result.returncode == 0, result.stderr
    assert f"package: {wheel_site}" in result.stderr  # the wheel's code, not the checkout's
    assert (elsewhere / "report" / "index.md").is_file()
    assert "quickstart.yaml" in result.stdout
    assert "3/4 no shipped policy to show: models/" in result.stdout  # said, with the fix
    assert "give --pretrained DIR" in result.stdout
    shipped = CHECKOUT / "models" / "td3-sbx-1e7-seed0"
    before = {p: p.read_bytes() for p in shipped.rglob("*") if p.is_file()}
    result = _softtrack(
        wheel_site, elsewhere, "evaluate", str(shipped), "-t", "circle", "--runs-dir", "runs"
    )
    assert result.returncode == 0, result.stderr
    assert "3-D RMSE" in result.stdout
    assert (elsewhere / "runs" / shipped.name / "tables" / "eval_metrics.parquet").is_file()
    assert {p: p.read_bytes() for p in shipped.rglob("*") if p.is_file()} == before
