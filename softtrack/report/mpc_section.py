"""The report's planning-cost section: what an MPC controller (``controller: mpc``) spends per
control step, as a multiple of real time."""

from __future__ import annotations

import numpy as np
import pandas as pd

from softtrack.report.document import Context, Doc

__all__ = ["planning_section"]


def planning_section(doc: Doc, ctx: Context) -> None:
    """Planning time per control step of every MPC group with evaluation metrics."""
    rows = []
    for group in ctx.groups:
        if group.controller != "mpc":
            continue
        times, worst = [], []
        for run in group.runs:
            if run.metrics is not None and "planning_time" in run.metrics:
                times.extend(pd.to_numeric(run.metrics["planning_time"], errors="coerce"))
                worst.extend(pd.to_numeric(run.metrics["planning_time_max"], errors="coerce"))
        if not times or not np.isfinite(times).any():
            continue
        spec = group.runs[0].record.load_spec()
        m, physics = spec.mpc, spec.env.physics
        control_dt = physics.dt * physics.steps_per_action
        mean = float(np.nanmean(times))
        rows.append(
            [
                group.label,
                f"{m.method}: {m.samples} samples × {m.horizon} steps × {m.iterations} iteration(s), "
                f"replanning every {m.replan_interval} steps",
                f"{mean * 1e3:.2f}",
                f"{float(np.nanmax(worst)) * 1e3:.1f}",
                f"{mean / control_dt:.1f}×",
            ]
        )
    if not rows:
        return
    doc.h(3, "Planning cost (MPC)")
    doc.table(
        [
            "controller",
            "planner",
            "planning time per control step (ms, mean)",
            "longest call (ms)",
            "multiple of real time",
        ],
        rows,
    )
    doc.p(
        "CPU time (the calling thread's) of the controller's call per control step during the "
        "evaluation episodes (mean over steps, trajectories and seeds; a replanning step costs "
        "the plan, the others only read it), on the CPU of the runs table: the cost on one core "
        "even when other processes shared the machine; real time is the control step "
        "(2 ms by default). A multiple above 1 means the planner cannot run in real time on "
        "this machine."
    )
