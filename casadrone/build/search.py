"""The build's search: every combination screened, bounded, and the promising ones raced
best-first, side by side, with the others pruned by their bound (branch and bound).

1. :func:`screened`: the combinations of the ``build:`` section, each refused without a solve
   where no frame of the box can fly it (:func:`casadrone.build.combos.refusal`);
2. :func:`bounded`: each other's point-mass race (:mod:`casadrone.build.bound`);
3. :func:`branch_and_bound`: in the order of their bounds, each combination is raced at its
   box's dominant frame where the box has one (:mod:`casadrone.build.dominance`: its race is
   the co-design's answer), else co-designed and raced
   (:func:`casadrone.build.solve.solve_combination`), on the pool (:func:`evaluate`), unless
   its bound is above the ``rank``-th best race time found so far (pruned: if the bound holds,
   it cannot enter the ranking). A combination whose bound is NaN is never pruned. Each one
   after the first starts from its :func:`neighbour`'s race (and a co-design from its
   geometry: continuation across the catalogue, neighbours differ by one part; alone, a
   combination starts from the template's geometry and the problem's lap starts).
4. :func:`confirmed`: each ranked combination raced at its dominant frame is checked by its
   race's gradient (first-order optimal over the box), moved by that gradient where the check
   fails (:mod:`casadrone.build.descent`: a few warm-started races), and co-designed from its
   frame where that does not settle or a certificate is asked for;
5. :func:`ranking`: the feasible races, fastest first, the first ``rank`` of them exact.

With more workers than one, a combination may be raced that one worker would have pruned
(its bound was below the threshold when it was handed out); the ranking is the same.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

from casadrone.airframe import with_theta
from casadrone.build.bound import point_mass_bound
from casadrone.build.combos import (
    Combination,
    combinations,
    least_mass_kg,
    refusal,
    valid_frames,
)
from casadrone.build.descent import descend
from casadrone.build.dominance import dominant_theta, stationary
from casadrone.build.pool import Pool
from casadrone.build.solve import (
    MAX_DERATES,
    BuildResult,
    codesign_problem,
    combination_start,
    current_derate,
    geometry_box,
    lap_options,
    race_dominant,
    race_track,
    solve_combination,
)
from casadrone.codesign.checks import template_of
from casadrone.config.airframe import AirframeConfig
from casadrone.config.build import BuildProblemConfig
from casadrone.config.io import ConfigError
from casadrone.config.parts import load_parts
from casadrone.limit.nlp import NlpSolution
from casadrone.limit.result import LapSeeds
from casadrone.progress import emit
from casadrone.results import AsDict


@dataclass(frozen=True)
class Build(AsDict):
    """A build: every combination's result (screened, pruned or raced), the ranking, the CPU."""

    problem: str
    laps: int
    results: tuple[BuildResult, ...]
    ranking: tuple[BuildResult, ...]
    backend: str
    workers: int
    cpu_s: float  # this process and every worker's co-design CPU together
    wall_time_s: float
    winner_airframe: AirframeConfig | None = None  # the winner's combination at its frame
    resumed: int = 0  # results read back from the folder of a stopped build, not solved again

    _omit = ("winner_airframe",)
    _properties = ("counts", "winner", "fronts")

    @property
    def counts(self) -> dict[str, int]:
        """How many combinations ended each way."""
        out: dict[str, int] = {}
        for r in self.results:
            out[r.outcome] = out.get(r.outcome, 0) + 1
        return out

    @property
    def winner(self) -> str | None:
        return self.ranking[0].label if self.ranking else None

    @property
    def fronts(self) -> dict[str, list[str]]:
        """The race time against the mass (lower is better) and against the energy left
        (higher is better): the raced feasible builds no other beats in both, fastest
        first (:func:`front`). Pruned builds are not on it: their race is not known."""
        return {"mass_kg": front(self.results, lambda r: r.mass_kg),
                "energy_left_wh": front(self.results, lambda r: -r.energy_left_wh)}


def front(results: tuple[BuildResult, ...], measure: Callable[[BuildResult], float]
          ) -> list[str]:
    """Labels of the feasible races not dominated in (race time, ``measure``), both minimised,
    fastest first."""
    ok = sorted((r for r in results if r.outcome == "raced" and r.feasible),
                key=lambda r: (r.race_s, measure(r)))
    out, best = [], math.inf
    for r in ok:
        if measure(r) < best:
            out.append(r.label)
            best = measure(r)
    return out


def screened(problem: BuildProblemConfig) -> tuple[list[Combination], list[BuildResult]]:
    """(the combinations a frame of the box may fly, the refused ones as results)."""
    template = template_of(problem)
    keys, lower, upper = geometry_box(problem)
    kept, refused = [], []
    for combo in combinations(load_parts(problem.build.parts_file), problem.build):
        why = refusal(template, combo, problem.build, keys, lower, upper)
        if why:
            refused.append(BuildResult(combo, "refused", reason=why))
        else:
            kept.append(combo)
    return kept, refused


def bound_of(problem: BuildProblemConfig, combo: Combination, laps: int | None,
             near: NlpSolution | None = None) -> float:
    """The combination's point-mass race (s) at the least mass of the box (solved from
    ``near``, a neighbour's relaxation, where given: :func:`bound_and_solution`)."""
    return bound_and_solution(problem, combo, laps, near)[0]


def bound_and_solution(problem: BuildProblemConfig, combo: Combination, laps: int | None,
                       near: NlpSolution | None = None) -> tuple[float, NlpSolution | None]:
    """The combination's bound and the relaxation's solution (:func:`point_mass_bound`)."""
    keys, lower, upper = geometry_box(problem)
    cfg = combination_start(problem, combo)
    light = min(valid_frames(cfg, keys, lower, upper), key=lambda f: least_mass_kg([f]))
    return point_mass_bound(light, least_mass_kg([light]), race_track(problem, laps),
                            lap_options(problem, cfg), near)


def bounded(problem: BuildProblemConfig, combos: list[Combination], laps: int | None
            ) -> list[tuple[float, Combination]]:
    """Each combination with its bound, lowest first (NaN bounds last, in catalogue order).
    In :func:`snake` order each relaxation is solved from the one before (neighbours differ by
    one part): a few seconds each instead of the straight-line starts' tens."""
    pairs, near = [], None
    for c in snake(combos):
        bound, sol = bound_and_solution(problem, c, laps, near)
        pairs.append((bound, c))
        near = sol if sol is not None else near
    return sorted(pairs, key=lambda p: (math.isnan(p[0]), p[0] if not math.isnan(p[0]) else 0))


def snake(combos: list[Combination]) -> list[Combination]:
    """``combos`` in boustrophedon order: by propeller, then motor and pack, each inner part's
    order reversed on every other run of its outer one, so that consecutive combinations differ
    in one part (the pack most often) and a run ends where the next begins (a 6S pack after a
    6S pack, not after a 650 mAh one, whose point-mass laps are far apart)."""
    rank: dict[str, dict[str, int]] = {kind: {} for kind in ("propeller", "motor", "pack")}
    for c in combos:
        for kind in rank:
            rank[kind].setdefault(getattr(c, kind).name, len(rank[kind]))

    def key(c: Combination) -> tuple[int, int, int]:
        p, m, k = (rank[kind][getattr(c, kind).name] for kind in ("propeller", "motor", "pack"))
        m = m if p % 2 == 0 else len(rank["motor"]) - 1 - m
        run = p * len(rank["motor"]) + m
        return p, m, k if run % 2 == 0 else len(rank["pack"]) - 1 - k
    return sorted(combos, key=key)


def threshold(raced: list[BuildResult], rank: int) -> float:
    """The ``rank``-th best feasible race time so far (inf while fewer are known)."""
    times = sorted(r.race_s for r in raced if r.feasible and math.isfinite(r.race_s))
    return times[rank - 1] if len(times) >= rank else math.inf


def branch_and_bound(problem: BuildProblemConfig, order: list[tuple[float, Combination]],
                     laps: int | None, pool: Pool,
                     record: Callable[[BuildResult], None] = lambda r: None,
                     held: tuple[BuildResult, ...] = ()) -> list[BuildResult]:
    """Co-design the combinations of ``order`` best-first on ``pool`` (module docstring), after
    the results ``held`` already (a resumed build's: they set the threshold and seed their
    neighbours as if just solved); ``record`` sees each new result as it is known."""
    done: list[BuildResult] = list(held)
    running: dict[Any, float] = {}
    for bound, combo in order:
        while len(running) >= pool.workers:
            _collect(pool, running, done, record)
        if bound > threshold(done, problem.build.rank):
            done.append(BuildResult(combo, "pruned", bound_s=bound, reason=(
                f"bound {bound:.4f} s is above the {problem.build.rank}-th best race "
                f"{threshold(done, problem.build.rank):.4f} s")))
            record(done[-1])
            continue
        near = neighbour(combo, done)
        seeds = LapSeeds() if near is None else LapSeeds(warm_starts=(near.race_lap,))
        running[pool.submit(evaluate, problem, combo, laps, bound, seeds,
                            None if near is None else near.theta,
                            None if near is None else near.end_soc)] = bound
    while running:
        _collect(pool, running, done, record)
    return done


def evaluate(problem: BuildProblemConfig, combo: Combination, laps: int | None,
             bound_s: float = math.nan, seeds: LapSeeds = LapSeeds(),
             start: dict[str, float] | None = None, soc: float | None = None) -> BuildResult:
    """One combination of the branch and bound: its box's dominant frame raced
    (:func:`race_dominant`) where the box has one (:mod:`casadrone.build.dominance`), else its
    frame co-designed and raced (:func:`solve_combination`, from ``start`` and ``seeds``).

    Where the dominant frame's race is not flown within the pack's limits, it is raced again:
    from its own lap with the limits it broke lowered by what its re-simulation broke them
    by, and again while the derated race still breaks one, at most :data:`MAX_DERATES` times
    (:func:`casadrone.build.solve.current_derate`: the lap's current rows hold at its nodes,
    and between them the re-simulation may exceed a limit by a tenth of an ampere:
    build-small's DA4052 + 1750 KV + 6S from DA4022's race, DA4022 + 2550 KV + 4S 1300 mAh
    alone); then from the problem's starts alone; then co-designed (the co-design reaches the
    frame from the template's, whose lap its starts may find where the frame's own do not),
    the co-design's result kept unless it finds no lap and the dominant race did. ``soc``:
    the neighbour's end state of charge, where the dominant race's first pass flies (one
    pass where this race ends near it)."""
    keys, lower, upper = geometry_box(problem)
    try:
        theta = dominant_theta(combination_start(problem, combo), keys, lower, upper)
    except ConfigError:
        theta = None  # the combination's own solve says why
    if theta is None:
        return solve_combination(problem, combo, laps, bound_s, seeds, start)
    fast = race_dominant(problem, combo, laps, theta, bound_s, seeds, soc)
    for _ in range(MAX_DERATES):  # a current over its limit between the solve's nodes
        derate = current_derate(fast)
        if derate is None:
            break
        again = race_dominant(problem, combo, laps, theta, bound_s,
                              LapSeeds(warm_starts=(fast.race_lap,)), fast.flown_soc, derate)
        fast = replace(again, cpu_s=again.cpu_s + fast.cpu_s)
    if not fast.feasible and seeds.warm_starts:  # the neighbour's race may mislead: alone
        again = race_dominant(problem, combo, laps, theta, bound_s)
        fast = replace(again, cpu_s=again.cpu_s + fast.cpu_s)
    if fast.feasible:
        return fast
    slow = solve_combination(problem, combo, laps, bound_s, seeds, start)
    kept = fast if math.isfinite(fast.race_s) and not math.isfinite(slow.race_s) else slow
    return replace(kept, cpu_s=slow.cpu_s + fast.cpu_s)


def confirmed(problem: BuildProblemConfig, results: list[BuildResult], laps: int | None,
              pool: Pool, record: Callable[[BuildResult], None] = lambda r: None
              ) -> list[BuildResult]:
    """``results`` with each ranked combination raced at its box's dominant frame checked by
    its race's gradient, on the pool (:func:`confirm`): kept where it is first-order optimal
    over the box, else moved there by the race's gradient, and co-designed where that does not
    settle or ``build.certify`` asks for a certificate (made of a co-design point). A co-design
    slower than its dominant race may let another combination in, which is checked in turn."""
    keys, lower, upper = geometry_box(problem)

    def settled(r: BuildResult) -> bool:
        return r.geometry_by != "dominance" or (not problem.build.certify and stationary(
            r.theta, r.race_gradient, keys, lower, upper))
    out, tried = list(results), set()
    while True:
        todo = [r for r in ranking(out, problem.build.rank)
                if not settled(r) and r.label not in tried]
        if not todo:
            return out
        tried |= {r.label for r in todo}
        running = {pool.submit(confirm, problem, r, laps): r for r in todo}
        while running:
            for fut in pool.first_done(list(running)):
                was = running.pop(fut)
                new = fut.result()
                out[next(i for i, r in enumerate(out) if r is was)] = new
                record(new)


def confirm(problem: BuildProblemConfig, r: BuildResult, laps: int | None) -> BuildResult:
    """A ranked dominant race ``r`` confirmed (:func:`confirmed`); its CPU and every solve's
    of the confirmation together.

    1. The check: the race's own dT/dθ at the frame meets the co-design's first-order
       optimality over the box (:func:`casadrone.build.dominance.stationary`: no key moves
       into the box and shortens the race), a second argument beside the dominance's, made of
       the lap's multipliers (no solve);
    2. where it fails, a descent from the frame by that gradient, one warm-started race per
       step (:func:`casadrone.build.descent.descend`), a few races where a co-design is one
       large NLP and a race;
    3. a co-design from the best frame (:func:`solve_combination`, its race as the first lap's
       seed) where the descent does not settle or a certificate is asked for."""
    keys, lower, upper = geometry_box(problem)
    best = r
    if not problem.build.certify:
        def race_at(theta: dict[str, float], near: BuildResult) -> BuildResult:
            # at the voltage the best race flew
            soc = near.flown_soc if math.isfinite(near.flown_soc) else near.end_soc
            # and under its current limits: the two races differ by θ alone
            return race_dominant(problem, r.combination, laps, theta, r.bound_s,
                                 LapSeeds(warm_starts=(near.race_lap,)), soc, near.derate)

        def flat(b: BuildResult) -> bool:
            return stationary(b.theta, b.race_gradient, keys, lower, upper)
        best, done = descend(r, keys, lower, upper, race_at, flat)
        if done:
            return best
    got = solve_combination(problem, r.combination, laps, r.bound_s,
                            LapSeeds(warm_starts=(best.race_lap,)), best.theta)
    if got.outcome == "raced" and math.isfinite(got.race_s):
        return replace(got, cpu_s=got.cpu_s + best.cpu_s)
    return replace(best, cpu_s=got.cpu_s + best.cpu_s, reason=(
        f"its co-design from the frame failed ({got.reason}): the frame's race is kept"))


def neighbour(combo: Combination, done: list[BuildResult]) -> BuildResult | None:
    """The nearest combination raced so far, whose co-designed geometry and race start
    ``combo``'s (continuation across the catalogue): one with the same propeller and motor,
    else the same propeller, else any, the latest raced first (their bounds are the closest:
    best-first order); None before the first race."""
    raced = [r for r in reversed(done) if r.race_lap is not None]
    c = combo

    def nearness(r: BuildResult) -> int:
        o = r.combination
        return (o.propeller.name == c.propeller.name) + (o.motor.name == c.motor.name) * (
            o.propeller.name == c.propeller.name)
    return max(raced, key=nearness, default=None)  # max keeps the first of equals: the latest


def _collect(pool: Pool, running: dict[Any, float], done: list[BuildResult],
             record: Callable[[BuildResult], None]) -> None:
    for fut in pool.first_done(list(running)):
        running.pop(fut)
        done.append(fut.result())
        record(done[-1])


def ranking(results: list[BuildResult], rank: int) -> tuple[BuildResult, ...]:
    """The feasible races, fastest first (ties by label), the first ``rank``."""
    ok = [r for r in results if r.outcome == "raced" and r.feasible]
    return tuple(sorted(ok, key=lambda r: (r.race_s, r.label))[:rank])


def certified(problem: BuildProblemConfig, ranked: tuple[BuildResult, ...]
              ) -> tuple[BuildResult, ...]:
    """The ranked builds with the certificate of their co-design point
    (:func:`casadrone.codesign.certificate.certify`: the lap re-solved with the frame fixed,
    the reduced gradient, the re-simulation)."""
    from casadrone.codesign.certificate import certify
    from casadrone.codesign.driver import prepare

    out = []
    for r in ranked:
        try:
            prep = prepare(codesign_problem(problem, combination_start(problem, r.combination)))
            out.append(replace(r, certificate=certify(prep, r.point)))
        except (RuntimeError, ValueError) as exc:  # a solver's error, a bad frame: say so
            out.append(replace(r, reason=f"certificate not made: {str(exc).splitlines()[0]}"))
    return tuple(out)


def announced(record: Callable[[BuildResult], None]) -> Callable[[BuildResult], None]:
    """``record`` after a progress line for the result (outcome, combination, race or why)."""
    def both(r: BuildResult) -> None:
        fig = f"race {r.race_s:.4f} s, " if math.isfinite(r.race_s) else ""
        emit("combination", f"{r.outcome} {r.label}: {fig}{r.reason or 'flies it'}"
             f" ({r.cpu_s:.1f} s CPU)", cpu_s=r.cpu_s)
        record(r)
    return both


def build(problem: BuildProblemConfig, laps: int | None = None,
          record: Callable[[BuildResult], None] = lambda r: None,
          held: tuple[BuildResult, ...] = ()) -> Build:
    """The build of ``problem`` (module docstring) for a race of ``laps`` laps (the
    ``build.laps`` or the track's when None) on the problem's ``backend``; ``record`` sees
    each new combination's result as it is known (and a progress line reports it). ``held``:
    the results of this build known before (a resumed one, :mod:`casadrone.build.resume`),
    neither bounded nor solved again; the CPU is this call's."""
    record = announced(record)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    laps = laps or problem.build.laps
    known = {r.label for r in held}
    kept, refused = screened(problem)
    for r in refused:
        if r.label not in known:
            record(r)
    order = bounded(problem, [c for c in kept if c.label not in known], laps)
    pool = Pool(problem.backend)
    try:
        results = branch_and_bound(problem, order, laps, pool, record,
                                   tuple(r for r in held if r.outcome != "refused"))
        results = confirmed(problem, results, laps, pool, record)
    finally:
        pool.close()
    ranked = ranking(results, problem.build.rank)
    if problem.build.certify:
        ranked = certified(problem, ranked)
    new = results[len(held) - sum(r.outcome == "refused" for r in held):]
    worker_cpu = sum(r.cpu_s for r in new) if pool.name != "serial" else 0.0
    return Build(problem.name, race_track(problem, laps).laps, tuple(refused + results), ranked,
                 pool.name, pool.workers, time.process_time() - cpu0 + worker_cpu,
                 time.perf_counter() - wall0, winner_airframe(problem, ranked),
                 resumed=len(held))


def winner_airframe(problem: BuildProblemConfig, ranked: tuple[BuildResult, ...]
                    ) -> AirframeConfig | None:
    """The first ranked build's airframe: its parts at its co-designed frame (None without)."""
    if not ranked:
        return None
    first = ranked[0]
    cfg = with_theta(combination_start(problem, first.combination), first.theta)
    return cfg.model_copy(update={"name": f"{problem.name}-winner"})
