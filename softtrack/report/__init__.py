"""Reports from the run store: figures (PNG) and tables (Markdown and HTML).

A report reads only the stored tables of the selected runs (``runs/<id>/tables/*.parquet``,
``run.json``, ``spec.yaml``), so it can be rebuilt at any time::

    from softtrack.report import build_report, select_report_runs
    from softtrack.store import RunStore

    store = RunStore("runs")
    build_report(select_report_runs(store, ["td3", "independent-td3"]), "reports/study",
                 "softtrack report td3 independent-td3 --out reports/study")
"""

from __future__ import annotations

from softtrack.lazy import lazy_exports

__all__ = ["EmptySelectionError", "build_report", "report_selection", "select_report_runs"]

_HOME = {
    "EmptySelectionError": "softtrack.report.select",
    "build_report": "softtrack.report.build",
    "report_selection": "softtrack.report.build",
    "select_report_runs": "softtrack.report.select",
}

__getattr__, __dir__ = lazy_exports(__name__, _HOME, __all__)
