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


def test_git_dirty_counts_code_not_shipped_results(tmp_path: Path) -> None:
    """A run created while an export to models/ (or a report) is uncommitted is still trained
    from committed code; a change to the code is dirty."""
    import subprocess

    from softtrack.store.provenance import git_info

    def git(*args: str) -> None:
        subprocess.run(["git", *args], cwd=tmp_path, check=True, capture_output=True)

    git("init", "-q")
    (tmp_path / "code.py").write_text("x = 1\n")
    git("add", ".")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "c")
    assert git_info.__wrapped__(str(tmp_path))[1] is False
    for result in ("models/run/run.json", "reports/study/index.md", "docs/x.md"):
        (tmp_path / result).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / result).write_text("{}")
    assert git_info.__wrapped__(str(tmp_path))[1] is False
    (tmp_path / "code.py").write_text("x = 2\n")
    assert git_info.__wrapped__(str(tmp_path))[1] is True


def test_a_cli_started_with_python_c_records_softtrack(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from softtrack.store import provenance

    argv = ["-c", "train", "x.yaml", "--seed", "1"]
    monkeypatch.setattr(provenance, "_cli_running", False)
    assert portable_command(argv, cwd=tmp_path)[0] == "-c"  # some other program's -c
    provenance.mark_cli()
    assert portable_command(argv, cwd=tmp_path) == ["softtrack", *argv[1:]]
