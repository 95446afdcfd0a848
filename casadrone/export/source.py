"""What an export is made from: an airframe (YAML or shipped name, with ``key=value`` overrides) or
one candidate of a finished run (decision letter A/B/C as in ``casadrone decide``, or a
``pareto.csv`` row), and the header every exported file carries.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from casadrone.airframe import THETA_KEYS, Airframe, build_airframe, with_theta
from casadrone.config.airframe import AirframeConfig, load_airframe
from casadrone.config.io import resolve_config
from casadrone.outfile import shown_path
from casadrone.rundir.store import PARETO, RunStore

#: Decision letters of ``casadrone decide`` and the methods they name.
LETTERS = {"A": "utopian", "B": "compromise", "C": "extreme"}


@dataclass(frozen=True)
class ExportSource:
    """The airframe to export and where it came from (for the header of every file)."""

    config: AirframeConfig
    airframe: Airframe
    origin: str  # "airframe SY250 (shipped configs/airframes/SY250.yaml)" or "run runs/q"
    candidate: str  # "-" for a plain airframe, else e.g. "A (utopian, pareto.csv row 3)"

    def header_lines(self, what: str) -> list[str]:
        """The provenance lines every export starts with (without comment markers)."""
        from casadrone import __version__

        a = self.airframe
        theta = ", ".join(f"{k}={getattr(self.config, k):g}" for k in THETA_KEYS
                          if getattr(self.config, k, None) is not None)
        J = a.inertia
        return [f"{what} written by casadrone {__version__}",
                f"source: {self.origin}; candidate: {self.candidate}",
                f"airframe: {self.config.name} ({a.family}); {theta}",
                f"mass {a.mass:.6g} kg; inertia about the centre of mass Ixx {J[0, 0]:.6g}, Iyy "
                f"{J[1, 1]:.6g}, Izz {J[2, 2]:.6g}, Ixy {J[0, 1]:.6g}, Ixz {J[0, 2]:.6g}, Iyz "
                f"{J[1, 2]:.6g} kg m^2; centre of mass {1000 * a.com[0]:+.2f}, "
                f"{1000 * a.com[1]:+.2f}, {1000 * a.com[2]:+.2f} mm from the hub",
                "casadrone body frame: x forward, y left, z up (other frames are stated below)"]


def airframe_source(airframe: str | Path, overrides: list[str] | None = None) -> ExportSource:
    """An airframe YAML or shipped name (``SY250``) with ``key=value`` overrides.

    Raises:
        ConfigError: a missing or invalid file, or a bad override.
    """
    path = resolve_config(airframe, "airframes")
    cfg = load_airframe(path, overrides or [])
    extra = f", overrides {' '.join(overrides)}" if overrides else ""
    return ExportSource(cfg, build_airframe(cfg), f"airframe {cfg.name} ({shown_path(path)}"
                        f"{extra})", "-")


def run_source(run_dir: str | Path, candidate: str) -> ExportSource:
    """One candidate of a finished run: ``A``/``B``/``C`` (the decisions of ``casadrone decide``)
    or a 0-based ``pareto.csv`` data row, on the run's airframe template with its fixed values.

    Raises:
        FileNotFoundError: not a run directory, or the run has not finished.
        ValueError: an unknown letter, a row outside the front, a run of a pymoo test problem.
        ConfigError: the candidate's geometry is refused by the airframe schema.
    """
    from casadrone.compare import run_candidates
    from casadrone.optimise.problem import Study, study_setup

    run_dir = Path(run_dir)
    store = RunStore(run_dir)
    problem = store.problem()
    if problem.test_problem is not None:
        raise ValueError(f"{run_dir}: a run of the test problem {problem.test_problem.name!r} has "
                         "no airframe to export")
    key = candidate.strip().upper()
    if key in LETTERS:
        (chosen,) = run_candidates(run_dir, (LETTERS[key],))
        theta, row = chosen.theta, chosen.row
        label = f"{key} ({chosen.method}, {PARETO} row {row})"
    elif key.isdigit():
        header, rows = store.read_pareto()
        row = int(key)
        if not rows:
            from casadrone.compare import empty_front

            raise ValueError(empty_front(run_dir))
        if row >= len(rows):
            raise ValueError(f"{run_dir}: {PARETO} has rows 0..{len(rows) - 1}, not {row}")
        n_var = len(Study(problem).variable_names)
        theta = dict(zip(header[:n_var], rows[row][:n_var], strict=True))
        label = f"{PARETO} row {row}"
    else:
        raise ValueError(f"--candidate: {candidate!r} is neither A, B, C nor a {PARETO} row number")
    template = study_setup(Study(problem)).template
    return candidate_source(template, theta, f"{run_dir.name}-{key}",
                            f"run {shown_path(run_dir)} (template {template.name})", label)


def candidate_source(template: AirframeConfig, theta: dict[str, float], name: str, origin: str,
                     candidate: str) -> ExportSource:
    """A candidate θ on a run's airframe template (raises ConfigError for refused geometry)."""
    cfg = with_theta(template, theta, name=name)
    return ExportSource(cfg, build_airframe(cfg), origin, candidate)


def source_of(source: str | Path, candidate: str | None = None,
              overrides: list[str] | None = None) -> ExportSource:
    """A run directory (needs ``candidate``) or an airframe (no candidate)."""
    path = Path(source)
    if path.is_dir():
        if candidate is None:
            raise ValueError(f"{source}: a run directory needs --candidate (A, B, C or a "
                             "pareto.csv row)")
        if overrides:
            raise ValueError(f"{source}: key=value overrides apply to an airframe, not to a run")
        return run_source(path, candidate)
    if candidate is not None:
        raise ValueError(f"--candidate {candidate}: {source} is an airframe, not a run directory")
    return airframe_source(source, overrides)

