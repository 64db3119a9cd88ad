"""softtrack animate: a shipped run drawn read-only, side by side, with its replay checked
against the stored evaluation; bad input refused before anything is replayed or written."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import imageio.v2 as imageio
import pytest
from typer.testing import CliRunner

from softtrack.cli import app

runner = CliRunner()
MODELS = Path(__file__).resolve().parents[1] / "models"
CENTRAL = MODELS / "td3-sbx-128-mirror-val-confirm-4e6-seed0"
INDEPENDENT = MODELS / "independent-td3-sbx-2e6-val-confirm-seed0"


def _digest(directory: Path) -> dict[str, str]:
    return {
        str(p.relative_to(directory)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(directory.rglob("*"))
        if p.is_file()
    }


def test_two_shipped_runs_side_by_side_read_only(tmp_path: Path) -> None:
    before = {run: _digest(run) for run in (CENTRAL, INDEPENDENT)}
    out, strip = tmp_path / "pair.gif", tmp_path / "pair.png"
    args = ["animate", str(CENTRAL), str(INDEPENDENT), "--out", str(out), "--strip", str(strip)]
    result = runner.invoke(app, [*args, "--width", "160", "--height", "120", "--fps", "3"])
    assert result.exit_code == 0, result.output
    notes = [line for line in result.stderr.splitlines() if line.startswith("note:")]
    assert len(notes) == 2 and all("stored evaluation" in note for note in notes)
    assert all(("to the last bit" in n) or ("differ" in n and "m;" in n) for n in notes)
    frames = imageio.mimread(out, memtest=False)
    assert len(frames) == 30 and frames[0].shape[:2] == (120, 320)
    assert imageio.imread(strip).shape[:2] == (6 * 120, 320)
    assert {run: _digest(run) for run in (CENTRAL, INDEPENDENT)} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pair.gif", "pair.png"]


def test_an_html_page_plays_every_trajectory(tmp_path: Path) -> None:
    out = tmp_path / "viewer.html"
    result = runner.invoke(
        app, ["animate", str(CENTRAL), "-t", "all", "--out", str(out), "--fps", "5"]
    )
    assert result.exit_code == 0, result.output
    page = out.read_text(encoding="utf-8")
    data = json.loads(page.split('type="application/json">', 1)[1].split("</script>", 1)[0])
    assert sorted(r["trajectory"] for r in data["rollouts"]) == ["circle", "figure8", "rectangle"]
    assert all(r["frames"] == 50 and r["arms"] == 2 and r["nodes"] == 21 for r in data["rollouts"])
    assert "http://" not in page and "https://" not in page  # nothing fetched at view time


def test_a_video_shows_one_trajectory(tmp_path: Path) -> None:
    result = runner.invoke(
        app, ["animate", str(CENTRAL), "-t", "all", "--out", str(tmp_path / "a.mp4")]
    )
    assert result.exit_code == 2 and "one trajectory" in result.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--out", "{tmp}/a.avi"], "unknown animation format .avi"),
        (["--out", "{tmp}/a.gif/b.mp4"], "a.gif is a file, not a directory"),
        (["--out", "{tmp}/a.gif", "--strip", "{tmp}/s.jpg"], "a film strip is a PNG"),
    ],
)
def test_bad_output_is_one_line_and_nothing_is_written(
    tmp_path: Path, args: list[str], message: str
) -> None:
    filled = [a.replace("{tmp}", str(tmp_path)) for a in args]
    if "a.gif/b.mp4" in filled[1]:
        (tmp_path / "a.gif").write_text("a file where a directory would go")
    before = sorted(p.name for p in tmp_path.iterdir())
    result = runner.invoke(app, ["animate", str(CENTRAL), *filled])
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and message in lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_missing_output_directories_are_created(tmp_path: Path) -> None:
    out = tmp_path / "videos" / "deep" / "a.gif"
    args = ["animate", str(CENTRAL), "--out", str(out), "--width", "160", "--height", "120"]
    result = runner.invoke(app, [*args, "--fps", "2"])
    assert result.exit_code == 0, result.output
    assert out.is_file()


def test_an_unknown_run_is_one_line(tmp_path: Path) -> None:
    result = runner.invoke(
        app,
        ["animate", "no-such-run", "--out", str(tmp_path / "a.gif"), "--runs-dir", str(tmp_path)],
    )
    assert result.exit_code == 2 and "no-such-run" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_report_html_replays_the_featured_controller_read_only(tmp_path: Path) -> None:
    before = _digest(CENTRAL)
    out = tmp_path / "report"
    result = runner.invoke(
        app,
        [
            "report",
            "td3-sbx-128-mirror-val-confirm",
            "--runs-dir",
            str(MODELS),
            "--out",
            str(out),
            "--html",
        ],
    )
    assert result.exit_code == 0, result.output
    page = (out / "interactive.html").read_text(encoding="utf-8")
    assert page.index("Best controllers per task") < page.index("featured controllers in 3-D")
    assert page.index("featured controllers in 3-D") < page.index('<h2 id="runs">')
    assert "study (TD3, 3 seeds)" in page and "http://" not in page.replace("http://www.w3.org", "")
    data = json.loads(
        page.split('<script id="data" type="application/json">', 1)[1].split("</script>")[0]
    )
    assert sorted(r["trajectory"] for r in data["rollouts"]) == ["circle", "figure8", "rectangle"]
    manifest = json.loads((out / "report.json").read_text(encoding="utf-8"))
    assert "interactive.html" in manifest["files"]
    assert _digest(CENTRAL) == before
