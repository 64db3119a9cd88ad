"""Reports from the run store: figures (PNG) and tables (Markdown and HTML).

A report reads only the stored tables of the selected runs (``runs/<id>/tables/*.parquet``,
``run.json``, ``spec.yaml``), so it can be rebuilt at any time::

    from softtrack.report import build_report
    from softtrack.store import RunStore
    from softtrack.store.selection import select_runs

    store = RunStore("runs")
    build_report(select_runs(store, ["td3", "independent-td3"]), "reports/study",
                 "softtrack report td3 independent-td3 --out reports/study")
"""

from __future__ import annotations

from softtrack.lazy import lazy_exports

__all__ = ["build_report", "report_selection"]

_HOME = {
    "build_report": "softtrack.report.build",
    "report_selection": "softtrack.report.build",
}

__getattr__, __dir__ = lazy_exports(__name__, _HOME, __all__)
