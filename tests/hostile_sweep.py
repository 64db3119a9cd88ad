"""A hostile sweep of the command line: faults across seven classes (paths of the wrong kind,
hostile specs, damaged tables and run records, resume, export, machine limits and signals,
concurrency), each injected into a fresh copy of six shipped runs and run as a user would.

Each fault ends as one of: ``held`` (a refusal is one line on stderr, exit 2 — 1 for a machine
limit, 128 + signal for a stop — and the store's files hash the same before and after; an
accepted input succeeds), ``traceback``, ``degraded`` (a hang, bad input accepted, several
error lines, a file's contents echoed, a check of its own failing) or ``lost`` (a refused
command changed the store). The tally ends the output; the highest resident memory of any
command is printed beside it.

    make hostile          # or: .venv/bin/python tests/hostile_sweep.py [WORKDIR]

The full-disk faults mount a 1-MB tmpfs and need root (skipped otherwise). docs/faults.md
("The hostile sweep") has the last tally.
"""

from __future__ import annotations

import hashlib
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

#: the command under attack; HOSTILE_SOFTTRACK names another (e.g. an older checkout's)
SOFTTRACK = os.environ.get("HOSTILE_SOFTTRACK") or str(Path(sys.executable).with_name("softtrack"))
MODELS = Path(__file__).resolve().parents[1] / "models"
SOURCE_RUNS = (
    "ddpg-sbx-1e6-seed0",
    "ddpg-sbx-1e6-seed1",
    "ddpg-sbx-1e6-seed2",
    "ppo-sbx-4e6-seed0",
    "ppo-sbx-4e6-seed1",
    "ppo-sbx-4e6-seed2",
)
RUN = "runs/ddpg-sbx-1e6-seed0"
SECRET = "hunter2-SECRET-LINE"


@dataclass
class Case:
    name: str
    klass: str
    setup: Callable[[Path], list[str]]
    expect: str = "refuse"  # refuse | ok | any
    limits: dict[int, int] = field(default_factory=dict)
    timeout: float = 120.0
    signal_after: float | None = None
    check: Callable[[Path, str, str], str | None] | None = None
    store: str = "runs"
    #: a refusal later than this (s) did the work first: degraded
    refuse_within: float | None = None
    env: dict[str, str] = field(default_factory=dict)


def store_digest(runs: Path) -> str:
    digest = hashlib.sha256()
    if not runs.is_dir():
        return "absent"
    for path in sorted(runs.rglob("*")):
        rel = path.relative_to(runs)
        if (rel.parts and rel.parts[0] == ".softtrack-catalog") or path.name == "run.lock":
            continue
        digest.update(str(rel).encode())
        if path.is_file() and not path.is_symlink():
            try:
                digest.update(path.read_bytes())
            except OSError:
                digest.update(b"unreadable")
    return digest.hexdigest()


#: a command of the sweep may use this much resident memory
MEMORY_LIMIT_MB = 2048


def run_case(case: Case, root: Path, template: Path) -> dict:
    work = root / case.name
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    shutil.copytree(template, work / "runs", symlinks=True)
    args = case.setup(work)
    before = store_digest(work / case.store)
    env = {
        **os.environ,
        "SOFTTRACK_RUNS_DIR": "runs",
        "SOFTTRACK_CACHE_DIR": str(root / "cache"),
        "COLUMNS": "200",
        **case.env,
    }

    def limit() -> None:
        os.setsid()
        signal.signal(signal.SIGINT, signal.SIG_DFL)  # a sweep run in the background ignores it
        for which, value in case.limits.items():
            resource.setrlimit(which, (value, value))

    peak_before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    start = time.monotonic()
    proc = subprocess.Popen(
        [SOFTTRACK, *args],
        cwd=work,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        preexec_fn=limit,
        text=True,
        errors="replace",
    )
    hung = False
    try:
        if case.signal_after is not None:
            try:
                out, err = proc.communicate(timeout=case.signal_after)
            except subprocess.TimeoutExpired:
                proc.send_signal(signal.SIGINT)
                out, err = proc.communicate(timeout=case.timeout)
        else:
            out, err = proc.communicate(timeout=case.timeout)
    except subprocess.TimeoutExpired:
        hung = True
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
    seconds = time.monotonic() - start
    peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    # the children's peak grows only when this command used more than every earlier one
    case_peak = peak_mb if peak_mb > peak_before else None
    after = store_digest(work / case.store)
    subprocess.run(["umount", "-q", str(work / "runs2")], capture_output=True)
    verdict, why = classify(case, proc.returncode, out, err, hung, before, after, work)
    if verdict == "held" and case_peak is not None and case_peak > MEMORY_LIMIT_MB:
        verdict, why = "degraded", f"{case_peak:.0f} MB of memory"
    if (
        verdict == "held"
        and case.refuse_within
        and proc.returncode
        and seconds > case.refuse_within
    ):
        verdict, why = "degraded", f"refused only after {seconds:.0f} s of work"
    return {
        "name": case.name,
        "class": case.klass,
        "verdict": verdict,
        "why": why,
        "rc": proc.returncode,
        "seconds": round(seconds, 1),
        "max_rss_mb_so_far": round(peak_mb),
        "stderr": err[-600:],
        "stdout": out[-300:],
    }


def classify(case, rc, out, err, hung, before, after, work) -> tuple[str, str]:
    if "Traceback" in err or "Traceback" in out:
        return "traceback", "traceback printed"
    if SECRET in err or SECRET in out:
        return "degraded", "echoed a file's contents"
    if hung:
        return "degraded", "hung"
    if case.expect == "refuse":
        if rc == 0:
            return "degraded", "accepted bad input"
        if after != before:
            return "lost", "store changed by a refused command"
        errors = [
            line
            for line in err.splitlines()
            if line.strip() and not line.startswith(("note:", "warning:"))
        ]
        if len(errors) != 1:
            return "degraded", f"{len(errors)} error lines"
        if rc not in (1, 2, 130, 143):
            return "degraded", f"exit {rc}"
    elif case.expect == "ok" and rc != 0:
        return "degraded", f"exit {rc} where success was expected"
    elif rc < 0 and not (out.strip() or err.strip()):  # "any": it may refuse, not die mute
        return "degraded", f"killed by signal {-rc} without a word"
    if case.check is not None:
        problem = case.check(work, out, err)
        if problem:
            return "degraded", problem
    return "held", ""


# ---- helpers to build faults -------------------------------------------------------------


def do(*steps: object) -> list[str]:
    """The command a case runs (the last argument), after the faults made by the others."""
    command = steps[-1]
    assert isinstance(command, list)
    return command


def write(path: Path, text: str | bytes) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


def fifo(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    os.mkfifo(path)
    return path


def replace_with_dir(path: Path) -> None:
    path.unlink()
    path.mkdir()
    (path / "x").write_text("x")


def edit_run_json(work: Path, run: str = RUN, **changes) -> None:
    path = work / run / "run.json"
    data = json.loads(path.read_text())
    data.update(changes)
    path.write_text(json.dumps(data))


def rewrite_table(work: Path, table: str, change: Callable) -> None:
    import pyarrow.parquet as pq

    path = work / RUN / "tables" / f"{table}.parquet"
    pq.write_table(change(pq.read_table(path)), path)


SPEC_OK = "experiments/quickstart.yaml"


def spec_file(work: Path, text: str | bytes, name: str = "s.yaml") -> str:
    write(work / name, text)
    return name


def workspace_command(out: str) -> list[str]:
    """A small ``softtrack workspace`` of the reachable transport spec writing to ``out``."""
    spec = (
        MODELS.parent
        / "experiments/variants/td3-sbx-128-3e6-mirror-fast-transport-fine-10ms-reachable.yaml"
    )
    search = ["--per-path", "1", "--population", "2", "--iterations", "1"]
    return ["workspace", str(spec), "--out", out, *search]


def quickstart_copy(work: Path) -> str:
    shutil.copy(MODELS.parent / SPEC_OK, work / "q.yaml")
    return "q.yaml"


def quickstart_text() -> str:
    return (MODELS.parent / SPEC_OK).read_text()


def cases() -> list[Case]:
    import pyarrow as pa

    out: list[Case] = []
    add = out.append
    GB = 1024**3

    # paths of the wrong kind
    add(
        Case(
            "runs-dir-is-file",
            "paths",
            lambda w: do(write(w / "f", "x"), ["runs", "--runs-dir", "f"]),
        )
    )
    add(
        Case(
            "runs-dir-is-fifo",
            "paths",
            lambda w: do(fifo(w / "p"), ["runs", "--runs-dir", "p"]),
            timeout=30,
        )
    )
    add(
        Case(
            "runs-dir-is-a-run",
            "paths",
            lambda w: ["runs", "--runs-dir", RUN],
            expect="any",
            check=lambda w, o, e: (
                None
                if ("run" in (o + e) and "runs directory is" in (o + e))
                else "a run directory given as runs dir: no hint"
            ),
        )
    )
    add(
        Case(
            "run-json-is-dir",
            "paths",
            lambda w: do(replace_with_dir(w / RUN / "run.json"), ["runs"]),
            expect="ok",
            check=lambda w, o, e: None if "is a directory" in o else "not said what run.json is",
        )
    )
    add(
        Case(
            "run-json-is-fifo",
            "paths",
            lambda w: do((w / RUN / "run.json").unlink(), fifo(w / RUN / "run.json"), ["runs"]),
            expect="ok",
            check=lambda w, o, e: None if "is a FIFO" in o else "not said what run.json is",
            timeout=30,
        )
    )
    add(
        Case(
            "tables-is-file",
            "paths",
            lambda w: do(
                shutil.rmtree(w / RUN / "tables"),
                write(w / RUN / "tables", "x"),
                ["compare", "ddpg-sbx", "ppo-sbx"],
            ),
            expect="any",
        )
    )
    add(
        Case(
            "metrics-table-fifo",
            "paths",
            lambda w: do(
                (w / RUN / "tables/eval_metrics.parquet").unlink(),
                fifo(w / RUN / "tables/eval_metrics.parquet"),
                ["compare", "ddpg-sbx", "ppo-sbx"],
            ),
            expect="any",
            timeout=60,
        )
    )
    add(
        Case(
            "report-out-is-file",
            "paths",
            lambda w: do(write(w / "rep", "x"), ["report", "ddpg-sbx", "-o", "rep"]),
        )
    )
    add(
        Case(
            "evaluate-spec-yaml-dir",
            "paths",
            lambda w: do(
                replace_with_dir(w / RUN / "spec.yaml"), ["evaluate", RUN, "-t", "circle"]
            ),
        )
    )
    add(
        Case(
            "export-dest-fifo",
            "paths",
            lambda w: do(fifo(w / "dest"), ["export", RUN, "dest"]),
            timeout=30,
        )
    )
    add(
        Case(
            "animate-out-dir",
            "paths",
            lambda w: do(
                (w / "anim.gif").mkdir(), ["animate", RUN, "-t", "circle", "-o", "anim.gif"]
            ),
            refuse_within=10,
        )
    )
    add(
        Case(
            "compare-figure-dir",
            "paths",
            lambda w: do(
                (w / "fig.png").mkdir(), ["compare", "ddpg-sbx", "ppo-sbx", "--figure", "fig.png"]
            ),
            check=lambda w, o, e: "names its own temporary" if ".tmp" in e else None,
        )
    )
    add(
        Case(
            "symlink-loop-run",
            "paths",
            lambda w: do((w / "runs/loop").symlink_to("loop"), ["runs"]),
            expect="ok",
        )
    )
    add(
        Case(
            "runs-dir-proc",
            "paths",
            lambda w: ["runs", "--runs-dir", "/proc/self"],
            expect="any",
            timeout=60,
        )
    )
    add(
        Case(
            "query-views-runs-dir-dev",
            "paths",
            lambda w: ["query", "--runs-dir", "/dev", "SELECT 1"],
            expect="any",
            timeout=60,
        )
    )

    # hostile specs
    bomb = "a: &a [x,x,x,x,x,x,x,x,x]\n" + "".join(
        f"{c}: &{c} [*{p},*{p},*{p},*{p},*{p},*{p},*{p},*{p},*{p}]\n"
        for p, c in zip("abcdefgh", "bcdefghi", strict=True)
    )
    add(
        Case(
            "yaml-alias-bomb",
            "specs",
            lambda w: ["validate", spec_file(w, bomb)],
            limits={resource.RLIMIT_AS: 4 * GB},
            timeout=60,
        )
    )
    add(
        Case(
            "yaml-deep-nesting",
            "specs",
            lambda w: ["validate", spec_file(w, "a: " + "[" * 50000 + "]" * 50000 + "\n")],
            timeout=60,
        )
    )
    add(
        Case(
            "base-cycle",
            "specs",
            lambda w: do(
                spec_file(w, "base: b.yaml\nname: a\n", "a.yaml"),
                ["validate", spec_file(w, "base: a.yaml\nname: b\n", "b.yaml")],
            ),
        )
    )
    add(Case("base-self", "specs", lambda w: ["validate", spec_file(w, "base: s.yaml\nname: s\n")]))
    add(Case("base-dir", "specs", lambda w: ["validate", spec_file(w, "base: runs\nname: s\n")]))
    add(
        Case(
            "base-dev-urandom",
            "specs",
            lambda w: ["validate", spec_file(w, "base: /dev/urandom\nname: s\n")],
            timeout=30,
        )
    )
    add(Case("spec-binary", "specs", lambda w: ["validate", spec_file(w, os.urandom(4096))]))
    add(
        Case(
            "spec-duplicate-key",
            "specs",
            lambda w: ["validate", spec_file(w, quickstart_text() + "\nname: other\n")],
        )
    )
    bad_overrides = {  # each refused by `validate` with one line
        "spec-dt-nan": "env.physics.dt=.nan",
        "spec-dt-inf": "env.physics.dt=1e400",
        "spec-steps-huge": "training.total_timesteps=1e30",
        "spec-lr-negative": "algo.learning_rate=-1",
        "set-unknown-path": "env.physics.nonsense=1",
        "set-no-equals": "env.physics.dt",
        "spec-period-tiny": "env.target.period=1e-300",
        "spec-steps-per-action-huge": "env.physics.steps_per_action=1000000000",
    }
    for name, override in bad_overrides.items():
        add(Case(name, "specs", lambda w, o=override: ["validate", quickstart_copy(w), "--set", o]))
    add(
        Case(
            "spec-name-ansi",
            "specs",
            lambda w: [
                "validate",
                spec_file(w, quickstart_text().replace("name: quickstart", 'name: "q\\e[2Jx"')),
            ],
        )
    )
    add(
        Case(
            "spec-latin1",
            "specs",
            lambda w: ["validate", spec_file(w, "name: caf\xe9\n".encode("latin-1"))],
        )
    )
    add(
        Case(
            "spec-bom",
            "specs",
            lambda w: ["validate", spec_file(w, "\ufeff" + quickstart_text())],
            expect="ok",
        )
    )
    add(Case("spec-empty", "specs", lambda w: ["validate", spec_file(w, "")]))
    add(Case("spec-list", "specs", lambda w: ["validate", spec_file(w, "- 1\n- 2\n")]))
    add(
        Case(
            "spec-secret-base",
            "specs",
            lambda w: do(
                write(w / "secret.txt", SECRET + "\n"),
                ["validate", spec_file(w, "base: secret.txt\nname: s\n")],
            ),
        )
    )
    add(Case("spec-secret-itself", "specs", lambda w: ["validate", spec_file(w, SECRET + ": [\n")]))
    add(Case("train-spec-dir", "specs", lambda w: ["train", "runs"]))

    # tables and run.json
    def truncate(w: Path, rel: str) -> None:
        p = w / RUN / rel
        p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])

    add(
        Case(
            "metrics-truncated-compare",
            "tables",
            lambda w: do(
                truncate(w, "tables/eval_metrics.parquet"), ["compare", "ddpg-sbx", "ppo-sbx"]
            ),
            expect="any",
        )
    )
    add(
        Case(
            "metrics-truncated-report",
            "tables",
            lambda w: do(
                truncate(w, "tables/eval_metrics.parquet"), ["report", "ddpg-sbx", "-o", "rep"]
            ),
            expect="any",
        )
    )
    add(
        Case(
            "metrics-renamed-columns",
            "tables",
            lambda w: do(
                rewrite_table(
                    w,
                    "eval_metrics",
                    lambda t: t.rename_columns([c + "_x" for c in t.column_names]),
                ),
                ["compare", "ddpg-sbx", "ppo-sbx"],
            ),
            expect="any",
        )
    )
    add(
        Case(
            "episodes-return-string",
            "tables",
            lambda w: do(
                rewrite_table(
                    w,
                    "train_episodes",
                    lambda t: t.set_column(
                        t.column_names.index("return"),
                        "return",
                        pa.array([str(v) for v in t.column("return").to_pylist()]),
                    ),
                ),
                ["report", "ddpg-sbx", "-o", "rep"],
            ),
            expect="any",
        )
    )
    add(
        Case(
            "metrics-inf-compare",
            "tables",
            lambda w: do(
                rewrite_table(
                    w,
                    "eval_metrics",
                    lambda t: t.set_column(
                        t.column_names.index("rmse_3d"),
                        "rmse_3d",
                        pa.array([float("inf")] * t.num_rows),
                    ),
                ),
                ["compare", "ddpg-sbx", "ppo-sbx"],
            ),
            expect="any",
            check=lambda w, o, e: (
                None
                if ("inf" in (o + e).lower() or "non-finite" in (o + e))
                else "inf metric not named"
            ),
        )
    )
    add(
        Case(
            "run-json-step-string",
            "tables",
            lambda w: do(edit_run_json(w, global_step="abc"), ["runs"]),
            expect="ok",
        )
    )
    add(
        Case(
            "run-json-negative-total",
            "tables",
            lambda w: do(edit_run_json(w, total_timesteps=-5), ["runs"]),
            expect="ok",
        )
    )
    add(
        Case(
            "run-json-nan-literal",
            "tables",
            lambda w: do(
                (w / RUN / "run.json").write_text(
                    (w / RUN / "run.json")
                    .read_text()
                    .replace('"steps_per_second": ', '"steps_per_second": NaN, "x": ', 1)
                ),
                ["runs"],
            ),
            expect="ok",
        )
    )
    add(
        Case(
            "run-json-list",
            "tables",
            lambda w: do((w / RUN / "run.json").write_text("[1,2]"), ["runs"]),
            expect="ok",
        )
    )
    add(
        Case(
            "run-json-huge",
            "tables",
            lambda w: do(
                (w / RUN / "run.json").write_text('{"pad": "' + "x" * 200_000_000 + '"}'), ["runs"]
            ),
            expect="ok",
            timeout=120,
        )
    )
    add(
        Case(
            "query-table-dir",
            "tables",
            lambda w: do(
                shutil.rmtree(w / RUN / "tables/eval_metrics.parquet", ignore_errors=True),
                (w / RUN / "tables/eval_metrics.parquet").unlink(),
                (w / RUN / "tables/eval_metrics.parquet").mkdir(),
                ["query", "SELECT count(*) FROM eval_metrics"],
            ),
            expect="any",
        )
    )
    add(
        Case(
            "model-zip-text",
            "tables",
            lambda w: do(
                (w / RUN / "model.zip").write_text("not a zip"),
                ["evaluate", RUN, "-t", "circle", "-m", "last"],
            ),
        )
    )
    add(
        Case(
            "model-zip-truncated-policy",
            "tables",
            lambda w: do(truncate(w, "model.zip"), ["evaluate", RUN, "-t", "circle"]),
        )
    )
    add(
        Case(
            "query-50-million-rows",
            "limits",
            lambda w: ["query", "SELECT range AS i, range * 2 AS j FROM range(50000000)"],
            expect="ok",
            timeout=300,
        )
    )
    add(Case("query-bad-sql", "tables", lambda w: ["query", "SELEC nonsense"]))
    add(
        Case(
            "compare-unknown-metric",
            "tables",
            lambda w: ["compare", "ddpg-sbx", "ppo-sbx", "--metric", "nope"],
        )
    )
    add(
        Case(
            "run-name-ansi",
            "tables",
            lambda w: do(edit_run_json(w, name="x\x1b[2Jy"), ["runs"]),
            expect="ok",
            check=lambda w, o, e: "terminal escape printed" if "\x1b[2J" in o + e else None,
        )
    )

    # resume and export
    add(
        Case(
            "resume-completed",
            "resume",
            lambda w: ["train", "--resume", "01M843X5KY62SE121WNMQSN5F0"],
        )
    )
    add(
        Case(
            "resume-unknown",
            "resume",
            lambda w: ["train", "--resume", "01ZZZZZZZZZZZZZZZZZZZZZZZZ"],
        )
    )
    add(
        Case(
            "resume-running-live-pid",
            "resume",
            lambda w: do(edit_run_json(w, status="running", pid=1, global_step=500), ["resume"]),
            expect="any",
        )
    )
    add(Case("export-into-runs-same-name", "export", lambda w: ["export", RUN, RUN]))
    add(Case("export-unknown-run", "export", lambda w: ["export", "nope", "dest"]))
    add(
        Case(
            "export-into-own-runs",
            "export",
            lambda w: ["export", RUN, "runs/copy"],
            expect="any",
        )
    )

    # limits and signals
    add(
        Case(
            "evaluate-ulimit-v",
            "limits",
            lambda w: ["evaluate", RUN, "-t", "circle"],
            limits={resource.RLIMIT_AS: 1 * GB},
            expect="any",
            timeout=120,
        )
    )
    add(
        Case(
            "runs-ulimit-n",
            "limits",
            lambda w: ["runs"],
            limits={resource.RLIMIT_NOFILE: 8},
            expect="any",
            timeout=60,
        )
    )
    add(
        Case(
            "query-ulimit-n",
            "limits",
            lambda w: ["query", "SELECT count(*) FROM runs"],
            limits={resource.RLIMIT_NOFILE: 12},
            expect="any",
            timeout=60,
        )
    )
    add(
        Case(
            "evaluate-ulimit-f",
            "limits",
            lambda w: ["evaluate", RUN, "-t", "circle"],
            limits={resource.RLIMIT_FSIZE: 2048},
            expect="any",
            timeout=180,
        )
    )
    add(
        Case(
            "evaluate-random-ctrl-c",
            "limits",
            lambda w: ["evaluate", RUN, "-t", "none", "--random", "400"],
            signal_after=25,
            expect="any",
            timeout=120,
            check=lambda w, o, e: (
                None if "kept the" in e else "Ctrl-C: nothing said about finished episodes"
            ),
        )
    )
    add(
        Case(
            "evaluate-while-locked",
            "concurrency",
            lambda w: do(
                write(
                    w / RUN / "run.lock",
                    json.dumps(
                        {"pid": os.getppid(), "host": os.uname().nodename, "activity": "train"}
                    ),
                ),
                ["evaluate", RUN, "-t", "circle"],
            ),
            expect="any",
        )
    )
    add(
        Case(
            "evaluate-metrics-readonly-file",
            "paths",
            lambda w: do(os.chmod(w / RUN / "tables", 0o555), ["evaluate", RUN, "-t", "circle"]),
            expect="any",
        )
    )
    add(
        Case(
            "runs-negative-total-shown",
            "tables",
            lambda w: do(edit_run_json(w, total_timesteps=-5), ["runs", "--format", "json"]),
            expect="any",
            check=lambda w, o, e: (
                "negative budget listed as a valid run"
                if "-5" in o and "unreadable" not in o + e
                else None
            ),
        )
    )
    add(
        Case(
            "spec-n-elem-huge",
            "specs",
            lambda w: ["validate", quickstart_copy(w), "--set", "env.physics.n_elem=100000000"],
            limits={resource.RLIMIT_AS: 8 * GB},
            timeout=60,
        )
    )
    add(
        Case(
            "spec-seeds-huge-list",
            "specs",
            lambda w: [
                "validate",
                quickstart_copy(w),
                "--set",
                "seeds=[" + ",".join(map(str, range(20000))) + "]",
            ],
            expect="any",
            timeout=60,
        )
    )
    add(
        Case(
            "workspace-out-file",
            "paths",
            lambda w: do(write(w / "o", "x"), workspace_command("o")),
            timeout=300,
        )
    )
    add(
        Case(
            "workspace-out-under-file",
            "paths",
            lambda w: do(write(w / "o", "x"), workspace_command("o/sub")),
            timeout=300,
        )
    )
    add(
        Case(
            "run-json-future-format",
            "tables",
            lambda w: do(edit_run_json(w, format_version=99), ["evaluate", RUN, "-t", "circle"]),
        )
    )
    add(
        Case(
            "upgrade-future-format",
            "tables",
            lambda w: do(edit_run_json(w, format_version=99), ["upgrade", RUN]),
        )
    )
    add(Case("compare-same-twice", "tables", lambda w: ["compare", "ddpg-sbx", "ddpg-sbx"]))
    add(Case("report-name-traversal", "paths", lambda w: ["report", "../../etc", "-o", "rep"]))
    add(
        Case(
            "runs-env-dir-missing",
            "paths",
            lambda w: ["query", "SELECT 1", "--runs-dir", "nowhere"],
        )
    )
    add(
        Case(
            "run-dir-name-ansi",
            "tables",
            lambda w: do(
                (w / RUN / "run.json").write_text("{"),
                (w / RUN).rename(w / "runs" / "x\x1b[31mred\nline"),
                ["runs"],
            ),
            expect="ok",
            check=lambda w, o, e: (
                "terminal escape printed"
                if "\x1b[31m" in o + e
                else "a newline broke the line"
                if "red\nline" in o
                else None
            ),
        )
    )
    add(
        Case(
            "compare-metrics-inf-both",
            "tables",
            lambda w: do(
                rewrite_table(
                    w,
                    "eval_metrics",
                    lambda t: t.set_column(
                        t.column_names.index("rmse_3d"),
                        "rmse_3d",
                        pa.array([float("-inf")] * t.num_rows),
                    ),
                ),
                ["compare", "ddpg-sbx", "ppo-sbx", "--metric", "rmse_3d"],
            ),
            expect="any",
            check=lambda w, o, e: (
                None if "non-finite" in (o + e) or "inf" in (o + e) else "-inf metric not named"
            ),
        )
    )
    add(
        Case(
            "report-metrics-nan",
            "tables",
            lambda w: do(
                rewrite_table(
                    w,
                    "eval_metrics",
                    lambda t: t.set_column(
                        t.column_names.index("rmse_3d"),
                        "rmse_3d",
                        pa.array([float("nan")] * t.num_rows),
                    ),
                ),
                ["report", "ddpg-sbx", "ppo-sbx", "-o", "rep"],
            ),
            expect="any",
        )
    )
    add(
        Case(
            "evaluate-random-zero",
            "specs",
            lambda w: ["evaluate", RUN, "-t", "none", "--random", "0"],
            expect="any",
        )
    )
    add(Case("evaluate-random-negative", "specs", lambda w: ["evaluate", RUN, "--random", "-3"]))
    add(Case("evaluate-nothing", "specs", lambda w: ["evaluate", RUN, "-t", "none"], expect="any"))
    add(
        Case(
            "tune-storage-not-db",
            "paths",
            lambda w: do(
                write(w / "db.sqlite", SECRET + "\n"),
                [
                    "report",
                    "ddpg-sbx",
                    "--study",
                    "x",
                    "--storage",
                    "sqlite:///db.sqlite",
                    "-o",
                    "rep",
                ],
            ),
        )
    )
    add(
        Case(
            "mlflow-uri-file",
            "paths",
            lambda w: do(write(w / "mlruns", "x"), ["sync", "mlflow", "ddpg-sbx"]),
            env={"MLFLOW_TRACKING_URI": "file:mlruns"},
            timeout=180,
        )
    )
    add(Case("full-disk-evaluate", "limits", full_disk("evaluate"), store="runs2", timeout=180))
    add(Case("full-disk-export", "limits", full_disk("export"), store="runs2", timeout=180))
    add(
        Case(
            "evaluate-twice-at-once",
            "concurrency",
            concurrent_evaluate,
            expect="any",
            timeout=180,
            check=tables_readable,
        )
    )
    add(
        Case(
            "export-twice-at-once",
            "concurrency",
            concurrent_export,
            expect="any",
            timeout=180,
            check=export_whole,
        )
    )
    return out


BACKGROUND: list[subprocess.Popen] = []


def _background(w: Path, args: list[str]) -> None:
    env = {**os.environ, "SOFTTRACK_RUNS_DIR": "runs"}
    BACKGROUND.append(
        subprocess.Popen(
            [SOFTTRACK, *args], cwd=w, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
    )
    time.sleep(2.0)


def concurrent_evaluate(w: Path) -> list[str]:
    _background(w, ["evaluate", RUN, "-t", "circle", "--random", "3"])
    return ["evaluate", RUN, "-t", "circle"]


def concurrent_export(w: Path) -> list[str]:
    _background(w, ["export", RUN, "dest"])
    return ["export", RUN, "dest"]


def _wait_background() -> None:
    while BACKGROUND:
        BACKGROUND.pop().wait(timeout=300)


def tables_readable(w: Path, o: str, e: str) -> str | None:
    import pyarrow.parquet as pq

    _wait_background()
    for path in (w / RUN / "tables").glob("*.parquet"):
        try:
            pq.read_table(path)
        except Exception as exc:
            return f"table {path.name} unreadable after two evaluations: {exc}"
    return None


def export_whole(w: Path, o: str, e: str) -> str | None:
    _wait_background()
    leftovers = [p.name for p in w.iterdir() if p.name.startswith(".")]
    if leftovers:
        return f"temporaries left: {leftovers}"
    if not (w / "dest" / "run.json").is_file():
        return "no export finished"
    return None


def full_disk(command: str):
    def setup(w: Path) -> list[str]:
        small = w / "runs2"
        small.mkdir()
        subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(small)], check=True)
        shutil.copytree(w / RUN, small / "run")
        with open(small / "fill", "wb") as f:
            try:
                f.write(b"x" * 10_000_000)
            except OSError:
                pass
        if command == "evaluate":
            return ["evaluate", "runs2/run", "-t", "circle", "--runs-dir", "runs2"]
        shutil.rmtree(small / "run")
        with open(small / "fill2", "wb") as f:
            try:
                f.write(b"x" * 10_000_000)
            except OSError:
                pass
        return ["export", RUN, "runs2/copy"]

    return setup


def main() -> int:
    root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="hostile-"))
    root.mkdir(parents=True, exist_ok=True)
    template = root / "_template"
    if not template.exists():
        template.mkdir()
        for name in SOURCE_RUNS:  # writable copies (an export is marked read-only)
            subprocess.run(
                [SOFTTRACK, "export", str(MODELS / name), str(template / name)],
                check=True,
                capture_output=True,
            )
            record = template / name / "run.json"
            data = json.loads(record.read_text())
            data["notes"] = {}
            record.write_text(json.dumps(data))
    only = os.environ.get("ONLY")  # a part of the case names, to run a few
    results = []
    for case in cases():
        if only and only not in case.name:
            continue
        if case.store == "runs2" and os.geteuid() != 0:
            print(f"skipped   {case.klass:11} {case.name:30} (needs root to mount a tmpfs)")
            continue
        result = run_case(case, root, template)
        results.append(result)
        print(
            f"{result['verdict']:9} {case.klass:11} {case.name:30} rc={result['rc']} "
            f"{result['seconds']}s {result['why']}",
            flush=True,
        )
        if result["verdict"] != "held":
            stderr = result["stderr"].strip().replace("\n", "\n            ")[-400:]
            print("    stderr:", stderr, flush=True)
    (root / "results.json").write_text(json.dumps(results, indent=1))
    tally = {kind: 0 for kind in ("held", "lost", "traceback", "degraded")}
    for r in results:
        tally[r["verdict"]] += 1
    classes = sorted({r["class"] for r in results})
    peak = max((r["max_rss_mb_so_far"] for r in results), default=0)
    print(
        f"hostile sweep: {len(results)} faults in {len(classes)} classes: "
        + ", ".join(f"{n} {kind}" for kind, n in tally.items())
        + f"; peak memory of a command {peak} MB; results in {root / 'results.json'}"
    )
    return 0 if len(results) == tally["held"] else 1


if __name__ == "__main__":
    sys.exit(main())
