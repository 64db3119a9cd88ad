"""The hostile sweep's verdicts (tests/hostile_sweep.py; the sweep itself runs by `make
hostile`)."""

from __future__ import annotations

from pathlib import Path

import hostile_sweep as sweep


def _case(expect: str) -> sweep.Case:
    return sweep.Case(name="x", klass="signals", setup=lambda work: [], expect=expect)


def test_a_command_killed_without_a_word_is_degraded_even_where_anything_goes() -> None:
    work = Path(".")
    verdict, why = sweep.classify(_case("any"), -11, "", "", False, {}, {}, work)
    assert verdict == "degraded" and "signal 11" in why
    # a refusal, a success, and a stop that says so stay held
    assert sweep.classify(_case("any"), 2, "", "error: x\n", False, {}, {}, work)[0] == "held"
    assert sweep.classify(_case("any"), 0, "ok\n", "", False, {}, {}, work)[0] == "held"
    assert sweep.classify(_case("any"), -2, "", "stopped\n", False, {}, {}, work)[0] == "held"
