"""Optimisation commands: run, resume, and on a run directory decide, compare and report."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer

from casadrone.cli.common import (
    JsonOpt,
    QuietOpt,
    app,
    bad_input,
    folder_creation_problem,
    print_json,
    progress_lines,
    reports_config_errors,
)
from casadrone.config.airframe import AirframeConfig, load_airframe
from casadrone.config.io import validate_data
from casadrone.config.problem import BackendConfig, ProblemConfig
from casadrone.rundir.store import (
    CONFIG,
    MANIFEST,
    PARETO,
    NotARunDirectory,
    RunDamaged,
    RunStore,
    check_new_run_dir,
    interrupted_creation,
)
from casadrone.verdict import default_baseline, format_verdicts, run_verdict


class BackendName(StrEnum):
    serial = "serial"
    processes = "processes"
    dask = "dask"


class DecideMethod(StrEnum):
    utopian = "utopian"
    compromise = "compromise"
    extreme = "extreme"


RunDirArg = Annotated[Path, typer.Argument(help="run directory (casadrone run --out DIR)")]
BackendOpt = Annotated[
    BackendName | None,
    typer.Option("--backend", help="evaluation backend (default: the problem's)"),
]
WorkersOpt = Annotated[
    int | None, typer.Option("-j", "--workers", min=1, help="worker processes")
]
SchedulerOpt = Annotated[
    str | None,
    typer.Option("--scheduler", help="Dask scheduler address (implies --backend dask)"),
]
ReferenceOpt = Annotated[
    list[str] | None,
    typer.Option("--reference", help="reference airframe (name or YAML); repeat for several "
                 "[default: SY250]"),
]
BaselineOpt = Annotated[
    list[str] | None,
    typer.Option("--reference", help="reference airframe (name or YAML); repeat for several; "
                 "the first is the baseline of the verdict [default: the problem's airframe]"),
]


# --------------------------------------------------------------------------------------------
# run, resume
# --------------------------------------------------------------------------------------------


def backend_config(base: BackendConfig, name: BackendName | None, workers: int | None,
                   scheduler: str | None) -> BackendConfig:
    """The problem's backend section with the command-line choices applied (validated)."""
    if scheduler is not None:
        if name not in (None, BackendName.dask):
            raise bad_input([f"--scheduler: only with --backend dask (got --backend {name})"])
        name = BackendName.dask
    data = base.model_dump()
    if name is not None:
        data["name"] = name.value
        if name is not BackendName.dask:
            data["scheduler"] = None
        if name is BackendName.serial:
            data["workers"] = 1
    if workers is not None:
        data["workers"] = workers
    if scheduler is not None:
        data["scheduler"] = scheduler
    cfg = validate_data(BackendConfig, data, "--backend", Path.cwd())
    if cfg.name == "serial" and workers not in (None, 1):
        typer.echo(f"-j {workers}: ignored by the serial backend (use --backend processes)",
                   err=True)
    return cfg


def require_run_dir(run_dir: Path) -> None:
    """Exit 2 unless ``run_dir`` is a run directory (it has config.yaml and manifest.json)."""
    if not run_dir.exists():
        raise bad_input([f"{run_dir}: no such run directory"])
    if not run_dir.is_dir():
        raise bad_input([f"{run_dir}: not a directory"])
    missing = [f for f in (CONFIG, MANIFEST) if not (run_dir / f).is_file()]
    why = interrupted_creation(run_dir)
    if why:
        raise bad_input([why])
    if missing:
        raise bad_input([f"{run_dir}: not a run directory (no {', '.join(missing)})"])


def open_problem(run_dir: Path) -> ProblemConfig:
    """The resolved problem of a run directory; an unreadable config.yaml is bad input."""
    try:
        return RunStore(run_dir).problem()
    except RunDamaged:
        raise  # one line naming the file (an edited input, a damaged manifest)
    except Exception as exc:  # noqa: BLE001 (yaml or pydantic: a damaged run directory)
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise bad_input([f"{run_dir / CONFIG}: not a valid resolved problem: {first}"]) from None


def run_summary(run_dir: Path) -> list[str]:
    """The run directory and a short summary of its front (from pareto.csv)."""
    from casadrone.indices import INDICES
    from casadrone.optimise.problem import Study

    store = RunStore(run_dir)
    m = store.manifest
    study = Study(store.problem())
    header, rows = store.read_pareto()
    n_var = len(header) - len(study.objective_names)
    if n_var < 0 or header[n_var:] != study.objective_names:
        raise RunDamaged(f"{run_dir / 'pareto.csv'}: columns {header} do not end with the "
                         f"objectives {study.objective_names}")
    lines = [f"run directory: {run_dir}",
             f"Pareto front: {len(rows)} design(s) from {m.get('n_evaluations')} evaluations "
             f"(pareto.csv)"]
    if not rows:
        lines.append("  no feasible design: every evaluation failed or broke a constraint "
                     "(see history.sqlite)")
        return lines
    for j, (name, sense) in enumerate(zip(study.objective_names, study.senses, strict=True)):
        col = [r[n_var + j] for r in rows]
        best = max(col) if sense == "max" else min(col)
        unit = INDICES[name].unit if name in INDICES else ""
        lines.append(f"  {name:<4} ({sense}) {min(col):>10.4g} … {max(col):<10.4g} {unit:<5} "
                     f"best {best:.6g}")
    lines.append(f"choose designs with: casadrone decide {run_dir}")
    return lines


def _failure_summary(run_dir: Path) -> list[str]:
    from collections import Counter

    hist = RunStore(run_dir).history()
    failed = [r for r in hist if r["status"] != "completed"]
    stages = Counter(r["stage"] for r in failed)
    lines = [f"{len(hist) - len(failed)} of {len(hist)} evaluations completed"]
    for stage, n in stages.most_common():
        example = next(r["reason"] for r in failed if r["stage"] == stage)
        lines.append(f"  {n:>6} failed at {stage}, e.g. {example}")
    return lines


@app.command("run")
@reports_config_errors
def run_command(
    problem: Annotated[Path, typer.Argument(help="problem YAML (problems/*.yaml)")],
    overrides: Annotated[
        list[str] | None,
        typer.Argument(help="dotted problem overrides, e.g. algorithm.generations=20 "
                       "objectives.0.index=J3"),
    ] = None,
    out: Annotated[Path, typer.Option("--out", "-o", help="new run directory")] = ...,  # type: ignore[assignment]
    backend: BackendOpt = None,
    workers: WorkersOpt = None,
    scheduler: SchedulerOpt = None,
    quiet: QuietOpt = False,
    verbose: Annotated[
        bool, typer.Option("--verbose", "-v", help="also print the set-up and the failures")
    ] = False,
) -> None:
    """Optimise: run a problem into a new run directory.

    Progress is one line per generation on stderr (with a bar on a terminal); at the end the run
    directory and a short summary of the Pareto front go to stdout. A killed run continues with
    'casadrone resume DIR' and ends exactly as an uninterrupted one.
    """
    from casadrone.optimise import runner
    from casadrone.optimise.checks import load_problem

    if quiet and verbose:
        raise bad_input(["--quiet and --verbose: choose one"])
    try:
        check_new_run_dir(out)
    except NotARunDirectory as exc:
        raise bad_input([f"--out: {exc}"]) from None
    unmakeable = folder_creation_problem(out)
    if unmakeable:
        raise bad_input([f"--out: {out}: {unmakeable}"])
    cfg = load_problem(problem, overrides or [])
    be = backend_config(cfg.backend, backend, workers, scheduler)
    if verbose:
        a = cfg.algorithm
        objectives = ", ".join(f"{o.index} ({o.sense or 'default'})" for o in cfg.objectives)
        typer.echo(f"problem {cfg.name}: {len(cfg.variables)} variables, objectives {objectives}; "
                   f"{a.name}, population {a.population}, {a.generations} generations, seed "
                   f"{cfg.seed}; backend {be.name} ({be.workers} worker(s)"
                   f"{', scheduler ' + be.scheduler if be.scheduler else ''}) -> {out}", err=True)
    try:
        runner.run(cfg, out, be, quiet=quiet)
    except NotARunDirectory as exc:
        raise bad_input([f"--out: {exc}"]) from None
    if verbose:
        for line in _failure_summary(out):
            typer.echo(line, err=True)
    typer.echo("\n".join(run_summary(out)))


@app.command()
@reports_config_errors
def resume(
    run_dir: RunDirArg,
    backend: BackendOpt = None,
    workers: WorkersOpt = None,
    scheduler: SchedulerOpt = None,
    quiet: QuietOpt = False,
) -> None:
    """Continue a killed run from its last checkpoint (same end as an uninterrupted run).

    A damaged last checkpoint falls back to the previous one; with neither (or a run killed
    before its first checkpoint) the run is rebuilt from its history.sqlite. A moved or copied
    run directory resumes from its own inputs. A run that has already finished is reported as
    complete (exit code 0): resuming is idempotent, so scripts may call it unconditionally.
    """
    from casadrone.optimise import runner

    require_run_dir(run_dir)
    problem = open_problem(run_dir)
    manifest = RunStore(run_dir).manifest
    if manifest.get("status") == "completed" and (run_dir / PARETO).is_file():
        typer.echo(f"{run_dir}: the run is already complete (finished {manifest.get('finished')}); "
                   "nothing to resume")
        typer.echo("\n".join(run_summary(run_dir)))
        return
    be = backend_config(problem.backend, backend, workers, scheduler)
    runner.resume(run_dir, be, quiet=quiet)
    typer.echo("\n".join(run_summary(run_dir)))


# --------------------------------------------------------------------------------------------
# decide, compare, report
# --------------------------------------------------------------------------------------------


def run_error(run_dir: Path, exc: Exception) -> typer.Exit:
    """A run-directory problem (not finished, empty front, unknown objective) as bad input."""
    text = str(exc)
    return bad_input([text if text.startswith(str(run_dir)) else f"{run_dir}: {text}"])


ObjectiveOpt = Annotated[
    str | None,
    typer.Option(help="objective of the extreme candidate C (default: the problem's first)"),
]


@app.command("decide")
@reports_config_errors
def decide_command(
    run_dir: RunDirArg,
    method: Annotated[
        DecideMethod | None,
        typer.Option(help="one method (default: all three, A utopian, B compromise, C extreme)"),
    ] = None,
    objective: ObjectiveOpt = None,
    reference: Annotated[str | None, typer.Option(
        "--reference", help="baseline airframe of the verdict (name or YAML) [default: the "
        "problem's airframe]")] = None,
    as_json: JsonOpt = False,
) -> None:
    """Choose designs on a finished run's front: A utopian, B compromise, C extreme.

    Reads pareto.csv and the problem's objective senses. A is the design closest to the utopian
    point, B the one closest to the front's mean point, C the best on --objective (default the
    problem's first objective), all in normalised objective space.

    Ends with the verdict against the baseline airframe (--reference): whether each candidate
    dominates it, the change of each objective and whether it is within the evaluation's noise
    (the same verdict opens the report).
    """
    from casadrone.compare import run_candidates

    require_run_dir(run_dir)
    problem = open_problem(run_dir)
    baseline = load_airframe(reference or default_baseline(problem))  # bad: exit 2 before work
    try:
        candidates = run_candidates(run_dir, (method.value,) if method else None, objective)
    except (FileNotFoundError, ValueError) as exc:
        raise run_error(run_dir, exc) from None
    if as_json:
        # "candidate" and "method": the keys decide --json had before Candidate.as_dict
        print_json([c.as_dict() | {"candidate": c.label, "method": c.method}
                    for c in candidates])
        return
    from casadrone.indices import INDICES

    for c in candidates:
        on = f" on {c.objective}" if c.objective else ""
        typer.echo(f"{c.label} {c.method}{on}: pareto.csv row {c.row}, distance "
                   f"{c.distance:.4f} (normalised objective space)")
        typer.echo("    theta: " + ", ".join(f"{k}={v:.6g}" for k, v in c.theta.items()))
        typer.echo("    objectives: " + ", ".join(
            f"{k}={v:.6g}" + (f" {INDICES[k].unit}" if k in INDICES else "")
            for k, v in c.objectives.items()))
    typer.echo(_verdict_block(run_dir, candidates, baseline), nl=False)


def _verdict_block(run_dir: Path, candidates: list, reference: AirframeConfig) -> str:
    """The verdict against the baseline for ``decide`` (empty for a test problem); a problem
    with a limit-lap objective is sent to the report (the baseline's limit lap takes minutes)."""
    from casadrone.optimise.problem import Study, study_setup

    study = Study(RunStore(run_dir).problem())
    if study.problem.test_problem is not None:
        return ""
    if study_setup(study).limit is not None:
        return (f"\nVerdict against {reference.name}: a limit-lap objective needs the baseline's "
                f"limit lap (minutes); casadrone report {run_dir} opens with it.\n")
    rv = run_verdict(study, candidates, reference)
    if not rv.verdicts:
        return (f"\nVerdict against {reference.name}: none, its lap failed "
                f"({rv.noise[0].status}).\n")
    return "\n" + format_verdicts(rv.verdicts, rv.how)


@app.command()
@reports_config_errors
def compare(
    run_dir: RunDirArg,
    reference: ReferenceOpt = None,
    objective: ObjectiveOpt = None,
    measured: Annotated[bool, typer.Option(
        "--measured", help="also the gains against the paper's measured Table 4 (a different "
        "time base: orientation only), in a block of their own")] = False,
    as_json: JsonOpt = False,
) -> None:
    """Benchmark-relative gains (paper Eq. 21, Tables 9-11) of the run's A/B/C candidates.

    Per candidate, reference airframe and interval: the % gain in split time, roll effort and
    opposing-pair thrust max/min, positive = better (faster, less effort, smaller extremes;
    effort and thrust by magnitude), against the reference flown on the run's track, controller
    and integrator (basis "simulated"). With --measured, also against the paper's Table 4
    (basis "measured": a different time base, orientation only), printed apart.
    """

    from casadrone.compare import compare_run, format_gains

    require_run_dir(run_dir)
    open_problem(run_dir)
    try:
        rows = compare_run(run_dir, tuple(reference or ("SY250",)), objective)
    except (FileNotFoundError, ValueError) as exc:
        raise run_error(run_dir, exc) from None
    simulated = [r for r in rows if r.basis == "simulated"]
    apart = [r for r in rows if r.basis == "measured"] if measured else []
    if as_json:
        print_json([r.as_dict() for r in simulated + apart])
        return
    typer.echo(format_gains(simulated), nl=False)
    if apart:
        typer.echo("\nAgainst the paper's measured Table 4 (different time base: orientation "
                   "only, not comparable with the gains above):")
        typer.echo(format_gains(apart), nl=False)


@app.command()
@reports_config_errors
def report(
    run_dir: RunDirArg,
    reference: BaselineOpt = None,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="report file (default: DIR/report.html)")
    ] = None,
    force: Annotated[bool, typer.Option(
        "--force", help="replace an existing --out file (the run's own report.html is always "
        "rewritten)")] = False,
    quiet: QuietOpt = False,
) -> None:
    """Write the HTML report of a run (front, candidates, gains over the references).

    Progress (the candidates' re-evaluation, then each section as it is built) goes to stderr;
    -q silences it. The report's path goes to stdout.
    """
    if out is not None and not force and (out.is_file() or out.is_symlink()) \
            and out.resolve() != (run_dir / "report.html").resolve():
        raise bad_input([f"--out: {out}: exists and was left untouched; choose another --out "
                         "or pass --force to replace it"])
    require_run_dir(run_dir)
    open_problem(run_dir)
    try:
        from casadrone.report import write_report
    except ModuleNotFoundError as exc:
        if exc.name != "casadrone.report":
            raise
        typer.echo("report: casadrone.report is not available in this installation", err=True)
        raise typer.Exit(1) from None
    try:
        with progress_lines("report", quiet):
            path = write_report(run_dir, references=tuple(reference) if reference else None,
                                out=out)
    except (FileNotFoundError, ValueError) as exc:
        raise run_error(run_dir, exc) from None
    typer.echo(str(path))
