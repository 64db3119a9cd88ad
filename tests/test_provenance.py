"""Recorded command lines: the program is `softtrack` and no argument is an absolute path."""

from __future__ import annotations

from pathlib import Path

import pytest

from softtrack.store.provenance import portable_command, portable_path


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (
            [".venv/bin/softtrack", "train", "experiments/study/td3-64-1e7.yaml"],
            ["softtrack", "train", "experiments/study/td3-64-1e7.yaml"],
        ),
        (
            [
                "{cwd}/softtrack/cli.py",
                "train",
                "{cwd}/experiments/x.yaml",
                "--seed",
                "0",
                "--runs-dir",
                "runs",
            ],
            ["softtrack", "train", "experiments/x.yaml", "--seed", "0", "--runs-dir", "runs"],
        ),
        (
            [
                "/usr/local/bin/softtrack",
                "train",
                "{cwd}/../specs/x.yaml",
                "--runs-dir={cwd}/../scratch/r",
            ],
            ["softtrack", "train", "../specs/x.yaml", "--runs-dir=../scratch/r"],
        ),
        (
            [
                "softtrack",
                "train",
                "../other/x.yaml",
                "--set",
                "seeds=[0, 1]",
                "--runs-dir",
                "~/runs",
            ],
            [
                "softtrack",
                "train",
                "../other/x.yaml",
                "--set",
                "seeds=[0, 1]",
                "--runs-dir",
                "~/runs",
            ],
        ),
        (
            ["{cwd}/experiments/reproduce_study.py", "--jobs", "2"],
            ["reproduce_study.py", "--jobs", "2"],
        ),
        ([], []),
    ],
)
def test_portable_command(tmp_path: Path, argv: list[str], expected: list[str]) -> None:
    argv = [a.replace("{cwd}", str(tmp_path)) for a in argv]
    got = portable_command(argv, cwd=tmp_path)
    assert got == expected
    assert not any(Path(a).is_absolute() for a in got)


def test_portable_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert portable_path(tmp_path / "experiments" / "a.yaml") == "experiments/a.yaml"
    assert portable_path("experiments/./a.yaml") == "experiments/a.yaml"
    assert portable_path(tmp_path.parent / "else" / "b.yaml") == "../else/b.yaml"
    assert portable_path("../else/./b.yaml") == "../else/b.yaml"
    assert portable_path(tmp_path) == "."
