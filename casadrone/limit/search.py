"""The two searches of ``casadrone limit-lap`` (docs/concepts/limit-lap.md, "Starts and
checks"): the fast path, the default, which solves from the two starts that won on the
measured frames and tracks (the grid-continuation starts: the fine grid on the paper track,
the coarse grid on the gate track), without grid rounds; and ``--certify``, every cold start
plus grid
rounds, whose agreement or spread (and the uncertainty of the sensitivities) is what a
certificate is made of. One registry, :data:`SEARCHES`; the CLI's flag and the benchmark
(``benchmarks/bench_limitlap_fastpath.py``) read it. :func:`lap_options` turns the settings a
user gives (:class:`casadrone.config.limitlap.LimitLapConfig`: the command's ``key=value``
arguments and options, a problem file's ``limit_lap:``) into the limit lap's options.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from casadrone.config.limitlap import COMMAND_GRID_ROUNDS, LimitLapConfig, Search, Solver, Start
from casadrone.limit.result import LimitLapOptions

__all__ = ["SEARCHES", "Search", "SearchSettings", "fatrop_allowed", "lap_options",
           "search_options"]


@dataclass(frozen=True)
class SearchSettings:
    """What a search changes in :class:`LimitLapOptions`: its cold starts, grid rounds and
    solver (where the track allows it: fatrop needs stages coupled only to neighbours, so a
    periodic track or collocation gets IPOPT)."""

    starts: tuple[Start, ...]
    grid_rounds: int
    solver: Solver
    fallback_starts: tuple[Start, ...] = ()  # solved only when ``starts`` verify no lap


#: The searches. ``fast``: see docs/concepts/limit-lap.md ("Starts and checks") and
#: benchmarks/RESULTS-limitlap-fastpath.md for the measurements behind the choice (fatrop from
#: the fine-grid start landed in worse optima than IPOPT: SY250 3.9276 against 3.8914 s, HS210
#: 3.8948 against 3.8307 s);
#: ``certify``: the four cold starts and COMMAND_GRID_ROUNDS rounds with IPOPT (the command's
#: default before the fast path).
SEARCHES: dict[Search, SearchSettings] = {
    "fast": SearchSettings(("library",), 0, "ipopt", ("coarse-grid", "fine-grid")),
    "certify": SearchSettings(LimitLapOptions.starts, COMMAND_GRID_ROUNDS, "ipopt"),
}


def fatrop_allowed(options: LimitLapOptions, periodic: bool) -> bool:
    """Whether fatrop can solve this NLP: shooting, and no periodic rows tying the last stage to
    the first (casadrone.limit.problem.check_inputs refuses it otherwise)."""
    return options.method == "shooting" and not periodic


def search_options(search: Search, options: LimitLapOptions, periodic: bool,
                   solver: Solver | None = None, grid_rounds: int | None = None
                   ) -> LimitLapOptions:
    """``options`` with ``search``'s starts, grid rounds and solver; ``solver`` and
    ``grid_rounds`` given by the user win. The search's fatrop becomes IPOPT where fatrop
    cannot solve the NLP (:func:`fatrop_allowed`)."""
    s = SEARCHES[search]
    chosen = solver if solver is not None else s.solver
    if solver is None and chosen == "fatrop" and not fatrop_allowed(options, periodic):
        chosen = "ipopt"
    return replace(options, starts=s.starts, solver=chosen, fallback_starts=s.fallback_starts,
                   grid_rounds=s.grid_rounds if grid_rounds is None else grid_rounds)


def lap_options(config: LimitLapConfig, periodic: bool,
                base: LimitLapOptions = LimitLapOptions()) -> LimitLapOptions:
    """The limit lap's options of ``config`` (on ``base``'s other settings): its model and
    check settings, then its search's starts, grid rounds and solver (:func:`search_options`;
    ``periodic``: the track ends where it starts), its own starts where it names them."""
    options = replace(base, intervals=config.intervals, attitude=config.attitude,
                      tilt_limit=config.tilt, resimulation=config.resimulation,
                      rotor_step=config.rotor_step, substeps=config.substeps)
    options = search_options(config.search, options, periodic, solver=config.solver,
                             grid_rounds=config.grid_rounds)
    return options if config.starts is None else replace(options, starts=config.starts,
                                                         fallback_starts=())
