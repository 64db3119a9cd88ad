"""``experiments/transport_seeds.py``: a transport recipe seed by seed against issue 62's per-seed
target, read from the shipped runs, its record and its figure."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "experiments"))
import transport_seeds as ts  # noqa: E402

RECIPE = "td3-sbx-128-mirror-tta-stop-transport-reachable-gs8-lr3e-4"
MODELS = ROOT / "models"


def test_the_shipped_seeds_are_read_and_judged() -> None:
    results = ts.read_seeds(RECIPE, [MODELS])
    assert [r.seed for r in results] == [0, 1, 2]
    for r in results:
        assert set(r.paths) == {"circle", "rectangle", "figure8"}
        assert 0.0 < r.worst_path < 0.1 and r.episodes == 20 and 0 <= r.carried <= 20
        assert r.minutes > 1.0
    assert ts.read_seeds(RECIPE, [MODELS, MODELS]) == results  # a seed counted once
    strict = ts.summary(results, at_most=0.001, carried=19)
    assert "0 of 3 seeds meet" in strict and strict.count("misses") == 3
    loose = ts.summary(results, at_most=1.0, carried=0)
    assert "3 of 3 seeds meet" in loose


def test_record_and_figure(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    record = tmp_path / "record.json"
    args = ["record", RECIPE, "--runs-dir", str(MODELS), "--record", str(record)]
    assert ts.main(args) == 0
    data = json.loads(record.read_text(encoding="utf-8"))
    assert data["recipe"] == RECIPE and len(data["seeds"]) == 3
    assert 0.0 < data["floors"]["circle"] < 0.025  # the reachable paths' recorded floor
    figure = tmp_path / "seeds.png"
    assert ts.main(["figure", str(record), "--figure", str(figure)]) == 0
    assert figure.stat().st_size > 10_000
    capsys.readouterr()
    assert ts.main(["record", "no-such-recipe", "--runs-dir", str(MODELS)]) == 2
    assert ts.main(["figure", str(tmp_path / "missing.json"), "--figure", str(figure)]) == 2
    err = capsys.readouterr().err
    assert "no evaluated, completed run of no-such-recipe" in err and "no record" in err
