"""Shared pytest hooks: a private default runs directory for every test, and the tally of
the fault-injection sweep (``make faults``)."""

from __future__ import annotations

from collections import Counter
from typing import Any

import pytest

#: what an injected fault did before softtrack handled it (``@pytest.mark.faults(kind)``)
FAULT_KINDS = ("lost", "traceback", "degraded", "held")

_tally: dict[str, Counter[str]] = {kind: Counter() for kind in FAULT_KINDS}


def _kind(item: Any) -> str | None:
    marker = item.get_closest_marker("faults") if hasattr(item, "get_closest_marker") else None
    if marker is None:
        return None
    kind = marker.args[0] if marker.args else marker.kwargs.get("kind", "held")
    if kind not in FAULT_KINDS:
        raise pytest.UsageError(f"{item.nodeid}: faults kind {kind!r}; one of {FAULT_KINDS}")
    return str(kind)


@pytest.fixture(autouse=True)
def _private_default_runs_dir(
    tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Commands run without --runs-dir write into a temporary directory, never the
    checkout's runs/."""
    monkeypatch.setenv("SOFTTRACK_RUNS_DIR", str(tmp_path_factory.mktemp("default-runs")))


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        _kind(item)  # an unknown kind is a usage error at once


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    kind = getattr(report, "fault_kind", None)
    counted = report.when == "call" or (report.when == "setup" and not report.passed)
    if kind is not None and counted:
        _tally[kind]["failed" if report.failed else "passed" if report.passed else "skipped"] += 1


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[Any]) -> Any:
    outcome = yield
    report = outcome.get_result()
    report.fault_kind = _kind(item)


def pytest_terminal_summary(terminalreporter: Any) -> None:
    ran = sum(sum(c.values()) for c in _tally.values())
    if not ran:
        return
    failed = {kind: _tally[kind]["failed"] for kind in FAULT_KINDS}
    skipped = sum(c["skipped"] for c in _tally.values())
    terminalreporter.write_line(
        f"fault sweep: {ran} faults injected ({skipped} skipped here); still "
        f"{failed['lost']} lost, {failed['traceback']} tracebacks, {failed['degraded']} degraded, "
        f"{failed['held']} regressions among the faults that already held"
    )
