"""The README's command tour runs as written in a fresh clone and rewrites no tracked file.

Every ``$S ...`` line of the README's "The command line" block runs in a clone of this
checkout, in order, with two substitutions a reader makes too: ``01M8…`` becomes the id the
``train`` line printed, and the training budget shrinks so the test takes minutes (the spec
still validates the reader's budget: ``validate`` runs it unchanged); ``train --resume`` of the
finished run may answer that there is nothing to resume. After each command,
``git status`` shows no tracked file changed, and new files only where the command says it
writes (``--out``, the ``export`` destination, the runs directory).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
TINY_BUDGET = (
    "training.total_timesteps=600 --set algo.learning_starts=100 "
    "--set training.checkpoint_interval=300"
)


def tour_commands(readme: str) -> list[str]:
    """The ``$S`` lines of the README's "The command line" block, without their comments."""
    block = readme.split("## The command line", 1)[1].split("```bash", 1)[1].split("```", 1)[0]
    lines = [line.split("  #", 1)[0].strip() for line in block.splitlines()]
    return [line for line in lines if line.startswith("$S ")]


def _git(clone: Path, *args: str) -> str:
    return subprocess.run(
        ["git", *args], cwd=clone, capture_output=True, text=True, check=True
    ).stdout


def _new_paths(clone: Path) -> tuple[list[str], list[str]]:
    """(tracked files changed or deleted, untracked paths) of the clone."""
    status = _git(clone, "status", "--porcelain", "--untracked-files=normal")
    changed, untracked = [], []
    for line in status.splitlines():
        (untracked if line.startswith("??") else changed).append(line[3:])
    return changed, untracked


def _outputs(command: str) -> list[str]:
    """Paths the command names as where it writes (a directory, or a file's top directory)."""
    named = re.findall(r"--(?:out|strip) (\S+)", command)
    if command.startswith("$S export "):
        named.append(command.split()[-1])
    allowed = []
    for path in named:
        parts = Path(path.rstrip("/")).parts
        if not Path(path).suffix:  # a directory it writes into
            allowed.append(path.rstrip("/") + "/")
        elif len(parts) == 1:  # a file in the checkout's top directory
            allowed.append(path)
        else:  # a file in a directory it creates: git shows that directory
            allowed.append(parts[0] + "/")
    return allowed


@pytest.mark.slow
def test_the_readme_tour_leaves_the_checkout_clean(tmp_path: Path) -> None:
    commands = tour_commands(README.read_text(encoding="utf-8"))
    assert len(commands) >= 15, "the README's command block moved: update this test"
    clone = tmp_path / "clone"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
    env = {k: v for k, v in os.environ.items() if k != "SOFTTRACK_RUNS_DIR"}
    softtrack = f"{sys.executable} -m softtrack.cli"
    run_id = ""
    for command in commands:
        line = command
        if " train " in f" {line} " and "--resume" not in line:
            line = line.replace("training.total_timesteps=2e5", TINY_BUDGET)
        line = line.replace("01M8…", run_id or "01M8…")
        done = subprocess.run(
            ["bash", "-c", f'S="{softtrack}"; {line}'],
            cwd=clone,
            env=env,
            capture_output=True,
            text=True,
            timeout=900,
        )
        finished = "--resume" in line and "already completed" in done.stderr  # nothing to resume
        assert done.returncode == 0 or (finished and done.returncode == 2), (
            f"{command}\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}"
        )
        if command.startswith("$S train ") and not run_id:
            found = re.search(r"\b(01[0-9A-Z]{24})\b", done.stdout + done.stderr)
            assert found, f"{command}: printed no run id\n{done.stdout}\n{done.stderr}"
            run_id = found.group(1)
        changed, untracked = _new_paths(clone)
        assert not changed, f"{command} changed tracked files: {changed}"
        allowed = _outputs(command) + [o for c in commands for o in _outputs(c)]
        stray = [p for p in untracked if not any(p.startswith(a) for a in allowed)]
        assert not stray, f"{command} left new files outside its outputs: {stray}"
    assert run_id
