"""MPC accuracy against planning budget: 3-D RMSE of sampling MPC at several sample counts and
horizons, beside the RL controllers, with the planning cost as a multiple of real time.

    taskset -c 0 .venv/bin/python benchmarks/bench_mpc_budget.py \\
        --budgets 32x50,64x50,64x50x2,64x50x3 --rl models/td3-sbx-128-mirror-val-confirm-4e6-seed* \\
        --figure mpc_budget.png --csv mpc_budget.csv

Each budget ``KxH[xI[xR]]`` is an MPC with K samples over H control steps, I sampling
iterations per plan (default 1) and a new plan every R control steps (default: the spec's
``replan_interval``; the other planner settings
from ``--spec``, default experiments/variants/mpc-mppi-64x50.yaml) evaluated like
`softtrack evaluate` on the study's circle, rectangle and figure-eight (one deterministic
episode each, seed 0), one after the other in this process on one core. It prints per budget
the six trajectory/arm cells, their mean, the planning time per control step (mean over the
steps: a replanning step costs the plan, the others only read it) and that time as a multiple
of real time (the 2-ms control step), then the cheapest budget whose mean 3-D RMSE is at or
below that of the best RL controller given with ``--rl`` (its seed mean over the stored
``eval_metrics``) and whether any budget is at or below 0.5 × the study in all six cells.
The figure plots mean 3-D RMSE against the multiple of real time, RL controllers and the study
as horizontal lines. ``--merge A.csv B.csv`` adds the rows of earlier runs of this script (a
sweep run in pieces) to the table, the summary and the figure.

The planning time is the planner's CPU time (its thread's) per control step, so the figure's
real-time factor is the cost on one core even while other processes share the machine.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from softtrack.evaluation.episode_tables import metrics_table  # noqa: E402
from softtrack.evaluation.episodes import EVAL_TRAJECTORIES, run_episode  # noqa: E402
from softtrack.report.reference import STUDY_RMSE_3D  # noqa: E402
from softtrack.rl.policy import mpc_controller  # noqa: E402
from softtrack.spec import load_spec  # noqa: E402
from softtrack.spec.env_config import env_config  # noqa: E402
from softtrack.store.provenance import cpu_kind  # noqa: E402
from softtrack.store.selection import select_one_run  # noqa: E402

DEFAULT_SPEC = ROOT / "experiments" / "variants" / "mpc-mppi-64x50.yaml"


KEYS = ["samples", "horizon", "iterations", "replan_interval"]


def parse_budgets(text: str, replan_interval: int) -> list[tuple[int, int, int, int]]:
    """``"16x50,64x50x2x1"`` → [(16, 50, 1, R), (64, 50, 2, 1)]: samples × horizon
    [× iterations [× replan interval]], R = ``replan_interval`` when not given."""
    out = []
    for item in text.split(","):
        parts = [int(p) for p in item.strip().split("x")]
        if len(parts) not in (2, 3, 4):
            raise SystemExit(f"--budgets: {item!r} is not SAMPLESxHORIZON[xITERATIONS[xREPLAN]]")
        out.append(
            (
                parts[0],
                parts[1],
                parts[2] if len(parts) >= 3 else 1,
                parts[3] if len(parts) == 4 else replan_interval,
            )
        )
    return out


def budget_label(budget: Any) -> str:
    """``64x50x2x5`` from a budget tuple or a row with the :data:`KEYS` columns."""
    values = budget if isinstance(budget, tuple) else (budget[key] for key in KEYS)
    return "x".join(str(int(value)) for value in values)


def study_cells() -> dict[tuple[str, int], float]:
    """The study's centralized TD3 3-D RMSE per (trajectory, arm), m."""
    return {
        (t, a): v for t, pair in STUDY_RMSE_3D["centralized"].items() for a, v in enumerate(pair)
    }


def evaluate_budget(
    spec_path: Path, budget: tuple[int, int, int, int], duration: float, trajectories: list[str]
) -> pd.DataFrame:
    """Metrics rows (one per trajectory and arm) of the MPC of ``spec_path`` with this budget
    (samples, horizon, iterations, replan interval), with its planning time per control
    step (s)."""
    spec = load_spec(
        spec_path, [f"mpc.{key}={value}" for key, value in zip(KEYS, budget, strict=False)]
    )
    config = env_config(spec)
    rows = []
    for trajectory in trajectories:
        episode = run_episode(mpc_controller(spec, 0), config, trajectory, duration)
        table = metrics_table(budget_label(budget), episode)
        for position, (key, value) in enumerate(zip(KEYS, budget, strict=False), start=1):
            table.insert(position, key, value)
        rows.append(table)
    out = pd.concat(rows, ignore_index=True)
    out["control_dt"] = config.sim.control_dt
    return out


def rl_means(run_dirs: list[str]) -> dict[str, float]:
    """Experiment name → seed mean of the mean 3-D RMSE over the six cells (stored)."""
    per_run: dict[str, list[float]] = {}
    for ref in run_dirs:
        record = select_one_run(ref)
        metrics = pd.read_parquet(record.table_path("eval_metrics"))
        metrics = metrics[metrics["trajectory"].isin(EVAL_TRAJECTORIES)]
        per_run.setdefault(record.info.name, []).append(float(metrics["rmse_3d"].mean()))
    return {name: float(np.mean(v)) for name, v in per_run.items()}


def write_figure(summary: pd.DataFrame, rl: dict[str, float], path: str) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 5), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    for (horizon, replan), part in summary.groupby(["horizon", "replan_interval"]):
        part = part.sort_values("realtime_factor")
        ax.plot(
            part["realtime_factor"],
            part["rmse_3d_mean"],
            "-o",
            label=f"MPC, horizon {horizon}, a plan every {replan} control step(s)",
        )
        for _, row in part.iterrows():
            ax.annotate(
                budget_label(row).replace("x", "×"),
                (row["realtime_factor"], row["rmse_3d_mean"]),
                fontsize=8,
                xytext=(4, 4),
                textcoords="offset points",
            )
    study = float(np.mean(list(study_cells().values())))
    ax.axhline(study, color="k", ls="--", lw=1, label=f"study centralized TD3 ({study:.3f} m)")
    ax.axhline(0.5 * study, color="0.5", ls=":", lw=1, label="0.5 × study")
    for j, (name, value) in enumerate(sorted(rl.items(), key=lambda kv: kv[1])):
        ax.axhline(value, color=f"C{j + 3}", lw=1.2, label=f"RL: {name} ({value:.3f} m)")
    ax.set_xscale("log")
    ax.set_xlabel("planning time per control step / control step (multiple of real time, one core)")
    ax.set_ylabel("mean 3-D RMSE over 3 trajectories × 2 arms (m)")
    ax.set_title(
        "Sampling MPC: accuracy against planning budget\n"
        "point labels: samples × horizon (control steps) × iterations × control steps per plan",
        fontsize=10,
    )
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--spec", default=str(DEFAULT_SPEC), help="MPC spec (planner settings)")
    parser.add_argument(
        "--budgets",
        default="32x50,64x50,64x50x2,64x50x3",
        help="comma-separated SAMPLESxHORIZON[xITERATIONS]",
    )
    parser.add_argument("--duration", type=float, default=10.0, help="episode length, s")
    parser.add_argument("--trajectories", default=",".join(EVAL_TRAJECTORIES))
    parser.add_argument("--rl", nargs="*", default=[], help="RL run directories to mark")
    parser.add_argument("--figure", help="write the figure here (PNG)")
    parser.add_argument("--csv", help="write one row per budget, trajectory and arm here")
    parser.add_argument(
        "--merge",
        nargs="*",
        default=[],
        metavar="CSV",
        help="rows of earlier runs (their --csv) to add before summarising",
    )
    args = parser.parse_args(argv)
    trajectories = args.trajectories.split(",")
    study = study_cells()
    spec_text = os.path.relpath(args.spec, ROOT)
    print(f"CPU: {cpu_kind()}; spec {spec_text}; {args.duration:g}-s episodes")
    replan = int(load_spec(Path(args.spec)).mpc.replan_interval)
    frames = [pd.read_csv(path) for path in args.merge]
    for frame in frames:  # rows written before budgets had a replan interval: the spec's
        if "replan_interval" not in frame:
            frame.insert(4, "replan_interval", replan)
    for budget in parse_budgets(args.budgets, replan) if args.budgets else []:
        started = time.perf_counter()
        rows = evaluate_budget(Path(args.spec), budget, args.duration, trajectories)
        frames.append(rows)
        cells = " ".join(
            f"{r.trajectory[:4]}{r.arm + 1} {r.rmse_3d:.4f}" for r in rows.itertuples()
        )
        factor = rows["planning_time"].mean() / rows["control_dt"].iloc[0]
        print(
            f"{budget_label(budget):12s} mean {rows['rmse_3d'].mean():.4f} m  [{cells}]  "
            f"{rows['planning_time'].mean() * 1e3:.2f} ms/step = {factor:.1f}x real time  "
            f"({time.perf_counter() - started:.0f} s)",
            flush=True,
        )
    if not frames:
        raise SystemExit("nothing to summarise: give --budgets or --merge")
    table = pd.concat(frames, ignore_index=True)
    summary = table.groupby(KEYS, as_index=False).agg(
        rmse_3d_mean=("rmse_3d", "mean"),
        planning_time=("planning_time", "mean"),
        control_dt=("control_dt", "first"),
    )
    summary["realtime_factor"] = summary["planning_time"] / summary["control_dt"]
    half = {
        key
        for key, part in table.groupby(KEYS)
        if all(r.rmse_3d <= 0.5 * study[(r.trajectory, r.arm)] for r in part.itertuples())
    }
    for _, row in summary.sort_values("realtime_factor").iterrows():
        print(
            f"  {budget_label(row):12s} mean {row['rmse_3d_mean']:.4f} m, "
            f"{row['realtime_factor']:.1f}x real time"
        )
    print(
        "at or below 0.5 × the study in all six cells: "
        + (", ".join(budget_label(k) for k in sorted(half)) or "none")
    )
    rl = rl_means(args.rl)
    if rl:
        best_name, best = min(rl.items(), key=lambda kv: kv[1])
        matching = summary[summary["rmse_3d_mean"] <= best].sort_values("realtime_factor")
        if len(matching):
            m = matching.iloc[0]
            print(
                f"cheapest budget at or below the best RL controller ({best_name}, {best:.4f} m): "
                f"{budget_label(m)}, "
                f"{m['rmse_3d_mean']:.4f} m, "
                f"{m['realtime_factor']:.1f}x real time"
            )
        else:
            print(f"no budget reaches the best RL controller ({best_name}, {best:.4f} m)")
    if args.csv:
        table.to_csv(args.csv, index=False)
    if args.figure:
        write_figure(summary, rl, args.figure)
        rows = Path(args.figure).with_suffix(".csv")  # redraw: --budgets "" --merge this file
        table.to_csv(rows, index=False)
        print(f"figure: {args.figure}; its rows: {rows}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
