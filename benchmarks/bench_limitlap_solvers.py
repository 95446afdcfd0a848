"""Benchmark: IPOPT and fatrop side by side on the limit-lap NLP of random Table 1 frames.

For ``--n`` random frames inside paper Table 1 (SY250 template, paper track, the seeds of
``bench_limitlap.py``), on one core, each solver solves the same NLP (default options, 40
intervals per leg) from the same starts:

- **cold**: from the frame's closed-loop guess (the ``closed-loop`` start of ``limit_lap``), or
  with ``--cold-start point-mass`` from its point-mass reference lifted to the full model (the
  ``point-mass`` start; the reference's own solves are timed apart, once per frame);
- **warm**: from the nearest neighbour's (normalised θ distance) cold solution by the same
  solver (IPOPT: primal-dual; fatrop: primal, its CasADi interface takes no multipliers);
- **near** (``--near FRAC``, default 0.01): each frame moved by ± FRAC of the Table 1 range in
  every key, solved from the frame's own cold solution by the same solver. IPOPT chooses its
  warm setting by the start's constraint violation (``solve(..., near=True)``,
  ``casadrone.limit.nlp.warm_solver``; also in the "warm" rows, where every start is far); the
  row "ipopt-far" has the far setting (``solve``'s default) on the same starts.

fatrop is measured alone (no IPOPT fallback): success, iterations, CPU time (process time) and
CPU time per iteration, and the lap against IPOPT's from the same start. ``--solvers`` may add
``ipopt-stage``: IPOPT on the stage-ordered NLP (what MUMPS's fill-in makes of that order; cold
only), and ``ipopt-monotone``: IPOPT with the monotone (Fiacco–McCormick) barrier strategy,
fatrop's, instead of the adaptive one (cold only; a control: how far two settings of the
reference solver itself land apart from the same start).

**Cross-check** (every cold solve of a solver other than ``ipopt``): IPOPT re-solves the NLP from
that solver's optimum (primal-dual, its warm setting chosen by the start's violation). If the
point is a local optimum of the same NLP, IPOPT stays there: the lap moves by ≤ 0.01 % in a few
iterations. It tells a different local optimum (the NLP is not convex) from a wrong answer.

``--ipopt-option KEY=VALUE`` (repeatable) adds an IPOPT option to every IPOPT solve, e.g.
``linear_solver=spral`` or ``mumps_pivot_order=0``, to measure the linear algebra.

Run: ``python benchmarks/bench_limitlap_solvers.py [--n 50] [--seed 0]``. Writes
``benchmarks/RESULTS-limitlap-solvers.md`` (``--out``).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.machine import cpu_time, markdown, with_summary  # noqa: E402
from benchmarks.table1 import frame_problem, moved_problem, nearest, unit_positions  # noqa: E402
from casadrone.airframe import build_airframe, random_thetas  # noqa: E402
from casadrone.config.airframe import load_airframe  # noqa: E402
from casadrone.config.io import load  # noqa: E402
from casadrone.config.track import TrackConfig  # noqa: E402
from casadrone.evaluate import DEFAULT_TRACK  # noqa: E402
from casadrone.limit import lap as limit  # noqa: E402
from casadrone.limit.nlp import NlpPoint, solve  # noqa: E402
from casadrone.limit.starts import prepare  # noqa: E402

HERE = Path(__file__).resolve().parent
_STAGE_IPOPT: dict = {}
_GUARD = [True]  # fatrop in a guarded child (the library's way); False: in-process, for stats


def _ipopt_stage(pb, w0) -> tuple[bool, float, int, str, NlpPoint]:
    """IPOPT on the stage-ordered NLP (the oracle fatrop uses), from w0."""
    import casadi as ca

    from casadrone.limit.nlp import ipopt_options
    from casadrone.limit.stagewise import fatrop_solver

    nlp = pb.full
    fs = fatrop_solver(nlp, nlp.tol, nlp.max_iter)
    if id(fs) not in _STAGE_IPOPT:
        _STAGE_IPOPT[id(fs)] = ca.nlpsol("ipopt_stage", "ipopt", fs.oracle,
                                         ipopt_options(nlp.tol, nlp.max_iter, False))
    S, o = _STAGE_IPOPT[id(fs)], fs.order
    lbx, ubx = pb.box
    out = S(x0=o.to_stage(np.clip(w0, lbx, ubx)), p=pb.P, lbx=o.to_stage(lbx),
            ubx=o.to_stage(ubx), lbg=o.to_stage(pb.rows[0], True),
            ubg=o.to_stage(pb.rows[1], True))
    st = S.stats()
    point = NlpPoint(o.from_stage(np.array(out["x"]).ravel()), np.zeros(len(w0)),
                     np.zeros(len(pb.rows[0])), np.zeros(len(pb.P)))
    return bool(st["success"]), float(out["f"]), int(st["iter_count"]), \
        str(st["return_status"]), point


_VARIANTS: dict = {}


def _ipopt_variant(nlp, name: str, overrides: dict):
    """A cold IPOPT instance on ``nlp``'s own functions with ``overrides`` on top of the
    library's cold options (built once per NLP and variant)."""
    from casadrone.limit.nlp import ipopt_solver

    key = (id(nlp), name)
    if key not in _VARIANTS:
        _VARIANTS[key] = ipopt_solver(nlp, f"limit_{name}", overrides)
    return _VARIANTS[key]


def _timed(pb, w0, solver: str, warm: NlpPoint | None = None) -> dict:
    """One solve by ``solver`` alone (fatrop's own result, not its IPOPT fallback);
    ``ipopt-far``: IPOPT with the far warm setting whatever the start; ``ipopt-monotone``:
    IPOPT with the monotone barrier strategy (cold)."""
    c0 = cpu_time()
    if solver == "ipopt-monotone":
        S = _ipopt_variant(pb.full, "monotone", {"mu_strategy": "monotone"})
        lbx, ubx = pb.box
        out = S(x0=np.clip(w0, lbx, ubx), p=pb.P, lbx=lbx, ubx=ubx, lbg=pb.rows[0],
                ubg=pb.rows[1])
        st = S.stats()
        point = NlpPoint(*(np.array(out[k]).ravel() for k in ("x", "lam_x", "lam_g", "lam_p")))
        return {"ok": bool(st["success"]), "f": float(out["f"]), "it": int(st["iter_count"]),
                "cpu": cpu_time() - c0, "status": str(st["return_status"]),
                "point": point}
    if solver == "ipopt-far":  # solve()'s default
        s = solve(pb.full, w0, pb.P, *pb.box, warm=warm, lbg=pb.rows[0], ubg=pb.rows[1])
        return {"ok": s.success, "f": s.objective, "it": s.iterations,
                "cpu": cpu_time() - c0, "status": s.return_status, "point": s.point}
    if solver == "ipopt-stage":
        ok, f, it, status, point = _ipopt_stage(pb, w0)
        return {"ok": ok, "f": f, "it": it, "cpu": cpu_time() - c0, "status": status,
                "point": point}
    if solver == "fatrop":
        from casadrone.limit.nlp import _solve_fatrop

        s = _solve_fatrop(pb.full, w0, pb.P, *pb.box, warm, *pb.rows, guard=_GUARD[0])
    else:
        s = solve(pb.full, w0, pb.P, *pb.box, warm=warm, lbg=pb.rows[0], ubg=pb.rows[1],
                  near=True)
    cpu = cpu_time() - c0
    return {"ok": s.success, "f": s.objective, "it": s.iterations, "cpu": cpu,
            "status": s.return_status, "point": s.point}


def _solver_of(pb, solver: str):
    """The nlpsol instance that ran the last cold solve of ``solver`` (for its statistics)."""
    from casadrone.limit.stagewise import fatrop_solver

    nlp = pb.full
    if solver == "fatrop":
        return fatrop_solver(nlp, nlp.tol, nlp.max_iter).cold
    if solver == "ipopt-stage":
        return _STAGE_IPOPT[id(fatrop_solver(nlp, nlp.tol, nlp.max_iter))]
    if solver == "ipopt-monotone":
        return _VARIANTS[(id(nlp), "monotone")]
    return nlp.cold


def profile(template_name: str, repeat: int = 1, solvers: tuple[str, ...] = (
        "ipopt", "fatrop", "ipopt-stage"), ipopt_option: tuple[str, ...] = ()) -> list[str]:
    """Per-iteration CPU of ``repeat`` cold solves of the template itself (closed-loop guess) by
    each solver (a row per solve), split into the NLP's function evaluations (CasADi's
    t_proc_nlp_* statistics) and the rest (the solver's own work: factorisation, line search,
    bookkeeping). Repeats show this machine's drift; two versions of the code are compared by
    running this alternately from their checkouts. ``ipopt_option``: the ``--ipopt-option``
    pairs already applied by :func:`main`, named in the header's command."""
    template = load_airframe(template_name)
    track = load(TrackConfig, DEFAULT_TRACK)
    options = limit.LimitLapOptions(intervals=limit.DEFAULT_INTERVALS["paper"])
    frame = build_airframe(template)
    pb = prepare(frame, track, options,
                 limit.frame_clearance_m(frame, template.prop_diameter_mm / 1000))
    w0 = limit.guess_from_trajectory(pb.full, limit.closed_loop_lap(frame, track), pb.x0)
    extra = "".join(f" --ipopt-option {o}" for o in ipopt_option)
    lines = [f"Per iteration, {template_name} cold from its closed-loop guess "
             f"(`python benchmarks/bench_limitlap_solvers.py --profile {template_name}{extra}`):",
             "",
             "| solver | lap (s) | iterations | CPU per iteration (ms) | of it: function "
             "evaluations (ms) | of it: the solver's own work (ms) |", "|---|---|---|---|---|---|"]
    _GUARD[0] = False  # the solver's statistics are those of this process's instance
    for solver in solvers:
        _timed(pb, w0, solver)  # builds once
        for _ in range(repeat):
            r = _timed(pb, w0, solver)
            st = _solver_of(pb, solver).stats()
            ev = sum(v for k, v in st.items() if k.startswith("t_proc_nlp"))
            it = max(r["it"], 1)
            lines.append(f"| {solver} | {r['f']:.6f} | {r['it']} | {1e3 * r['cpu'] / it:.1f} | "
                         f"{1e3 * ev / it:.1f} | {1e3 * (r['cpu'] - ev) / it:.1f} |")
    return lines


def summary_row(cold: dict, warm: dict, n: int, cold_start: str = "closed-loop"
                ) -> tuple[str, str, str]:
    """The performance page's row: median CPU per iteration and per warm solve, both solvers."""
    def per_it(runs):
        return 1e3 * float(np.median([r["cpu"] / r["it"] for r in runs if r["ok"] and r["it"]]))

    def med_cpu(runs):
        return float(np.median([r["cpu"] for r in runs])) if runs else float("nan")

    def max_cpu(runs):
        return max(r["cpu"] for r in runs) if runs else float("nan")

    def verdict(ok: list[str]) -> str:  # issue #19's targets, each on its own
        return f"met by {' and '.join(ok)}" if ok else "not met"

    solvers = ("ipopt", "fatrop")
    cold_ok = [s for s in solvers if med_cpu(cold[s]) <= 3.0 and max_cpu(cold[s]) <= 15.0]
    warm_ok = [s for s in solvers if med_cpu(warm[s]) <= 0.25]
    return (f"limit-lap NLP of {n} random Table 1 frames, IPOPT and fatrop from the same starts "
            f"({cold_start} cold), one core",
            f"CPU per iteration {per_it(cold['ipopt']):.1f} ms (IPOPT), "
            f"{per_it(cold['fatrop']):.1f} ms (fatrop); cold solve {med_cpu(cold['ipopt']):.1f} / "
            f"{med_cpu(cold['fatrop']):.1f} s, warm {med_cpu(warm['ipopt']):.2f} / "
            f"{med_cpu(warm['fatrop']):.2f} s median, cold max {max_cpu(cold['ipopt']):.1f} / "
            f"{max_cpu(cold['fatrop']):.1f} s (target cold ≤ 3 s median and ≤ 15 s max: "
            f"{verdict(cold_ok)}; warm ≤ 0.25 s median: {verdict(warm_ok)})",
            f"`python benchmarks/bench_limitlap_solvers.py --n {n} --cold-start {cold_start}`")


def _row(label: str, runs: list[dict]) -> list[str]:
    ok = [r for r in runs if r["ok"]]
    cpu = [r["cpu"] for r in runs]
    per = [r["cpu"] / r["it"] for r in ok if r["it"]]
    med = np.median
    return [f"| {label} | {len(ok)}/{len(runs)} | {med([r['it'] for r in ok]):.0f} | "
            f"{med(cpu):.2f} | {max(cpu):.2f} | {1e3 * med(per):.1f} |"]


def near_solves(template, thetas, cold, args, track, options) -> dict[str, list]:
    """Each frame moved by ± ``args.near`` of the Table 1 range in every key (seeded), solved
    from its own cold solution: IPOPT (its warm setting chosen by the start), IPOPT with the far
    setting forced, fatrop (primal start)."""
    rng = np.random.default_rng(args.seed + 1)
    runs: dict[str, list] = {s: [] for s in ("ipopt", "ipopt-far", "fatrop")
                             if s.removesuffix("-far") in cold}
    for i, theta in enumerate(thetas):
        made = moved_problem(template, theta, args.near, rng, f"near{i}", track, options)
        if made is None:  # every move of this frame is an impossible body
            continue
        pb = made[1]
        for s in runs:
            own = cold["fatrop" if s == "fatrop" else "ipopt"][i]
            if own["ok"]:
                runs[s].append(_timed(pb, own["point"].w, s, warm=own["point"]) | {"frame": i})
        print("near", i, *(f"{s}: {runs[s][-1]['f']:.5f} {runs[s][-1]['it']} it "
                           f"{runs[s][-1]['cpu']:.2f} s" for s in runs if runs[s]), flush=True)
    return runs


def cross_check(problems, cold: dict) -> dict[str, list]:
    """IPOPT from each other solver's cold optimum (primal-dual; ``solve(..., near=True)``)."""
    out: dict[str, list] = {}
    for s, runs in cold.items():
        if s == "ipopt":
            continue
        out[s] = []
        for i, r in enumerate(runs):
            if r["ok"] and np.any(r["point"].lam_g):  # ipopt-stage keeps no multipliers
                c = _timed(problems[i], r["point"].w, "ipopt", warm=r["point"])
                out[s].append(c | {"frame": i, "from": r["f"]})
    return out


def _pct(rel: np.ndarray) -> str:
    """Median and largest of relative differences, in per cent, and how many are ≤ 0.01 %."""
    if not len(rel):
        return "no frames"
    return (f"median {100 * np.median(rel):.5f} %, max {100 * rel.max():.5f} %; within "
            f"0.01 %: {int(np.sum(rel <= 1e-4))}/{len(rel)}")


def _cross_lines(cross: dict[str, list], cold: dict) -> list[str]:
    lines = []
    ref = {i: c["f"] for i, c in enumerate(cold["ipopt"]) if c["ok"]}
    for s, runs in cross.items():
        ok = [r for r in runs if r["ok"]]
        if not ok:
            continue
        moved = np.array([abs(r["f"] - r["from"]) / r["from"] for r in ok])
        other = np.array([abs(r["from"] - ref[r["frame"]]) / ref[r["frame"]] for r in ok
                          if r["frame"] in ref])
        lines.append(
            f"Cross-check, IPOPT from {s}'s optimum ({len(ok)}/{len(runs)} converged): the lap "
            f"moves by {_pct(moved)}; iterations median "
            f"{np.median([r['it'] for r in ok]):.0f}, CPU median "
            f"{np.median([r['cpu'] for r in ok]):.2f} s. ({s}'s optimum against IPOPT's own "
            f"from the same start: {_pct(other)}.)")
    return ["", *lines] if lines else []


def _agreement(runs: dict[str, list], label: str) -> list[str]:
    """How far fatrop's and the far setting's laps are from IPOPT's on the same starts."""
    ref = {r["frame"]: r for r in runs.get("ipopt", []) if r["ok"]}
    out = []
    for s in ("ipopt-far", "fatrop"):
        rel = np.array([abs(r["f"] - ref[r["frame"]]["f"]) / ref[r["frame"]]["f"]
                        for r in runs.get(s, []) if r["ok"] and r["frame"] in ref])
        if len(rel):
            out.append(f"{label.capitalize()} starts, both converged ({len(rel)} frames): "
                       f"|{s} − IPOPT| / IPOPT lap median {100 * np.median(rel):.4f} %, max "
                       f"{100 * rel.max():.4f} %; within 0.01 %: "
                       f"{int(np.sum(rel <= 1e-4))}/{len(rel)}.")
    return ["", *out] if out else []


def _with_ipopt_options(pairs: list[str]) -> None:
    """Every IPOPT instance built from now on gets these options (``KEY=VALUE``: numbers as
    numbers, anything else as text)."""
    import casadrone.limit.nlp as nlp_module

    extra: dict = {}
    for pair in pairs:
        key, _, value = pair.partition("=")
        try:
            extra[key] = int(value)
        except ValueError:
            try:
                extra[key] = float(value)
            except ValueError:
                extra[key] = value
    base = nlp_module.ipopt_options

    def with_extra(*a, **k) -> dict:
        opts = base(*a, **k)
        opts["ipopt"].update(extra)
        return opts

    nlp_module.ipopt_options = with_extra


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--template", default="SY250")
    ap.add_argument("--solvers",
                    help="comma-separated: ipopt (required), fatrop, ipopt-stage, ipopt-monotone "
                         "(default ipopt,fatrop; with --profile ipopt,fatrop,ipopt-stage and any "
                         "one of them alone)")
    ap.add_argument("--out", type=Path, default=HERE / "RESULTS-limitlap-solvers.md")
    ap.add_argument("--near", type=float, default=0.01,
                    help="near warm starts: each frame moved by this fraction of the range")
    ap.add_argument("--cold-start", choices=("closed-loop", "point-mass"), default="closed-loop",
                    help="the guess of the cold solves (module docstring)")
    ap.add_argument("--ipopt-option", action="append", default=[], metavar="KEY=VALUE",
                    help="an IPOPT option added to every IPOPT solve (repeatable)")
    ap.add_argument("--profile", metavar="AIRFRAME",
                    help="only print the per-iteration split of one cold solve of AIRFRAME")
    ap.add_argument("--repeat", type=int, default=1,
                    help="with --profile: solves per solver (one row each)")
    args = ap.parse_args(argv)
    if args.ipopt_option:
        _with_ipopt_options(args.ipopt_option)
    if args.profile:
        print("\n".join(profile(args.profile, args.repeat, tuple(
            (args.solvers or "ipopt,fatrop,ipopt-stage").split(",")), tuple(args.ipopt_option))))
        return 0
    args.solvers = args.solvers or "ipopt,fatrop"
    SOLVERS = tuple(args.solvers.split(","))
    template = load_airframe(args.template)
    track = load(TrackConfig, DEFAULT_TRACK)
    options = limit.LimitLapOptions(intervals=limit.DEFAULT_INTERVALS["paper"])
    thetas, _ = random_thetas(template, args.n, args.seed)
    keys = list(thetas[0])
    unit = unit_positions(thetas)
    problems, cold = [], {s: [] for s in SOLVERS}
    guess_cpu: list[float] = []  # the cold guess's own CPU per frame (closed loop or point mass)
    for i, theta in enumerate(thetas):
        frame, pb = frame_problem(template, theta, f"frame{i}", track, options)
        c0 = cpu_time()
        if args.cold_start == "point-mass":
            w0 = pb.lifted  # the point-mass reference (three point-mass solves), lifted
        else:
            traj = limit.closed_loop_lap(frame, track, None)  # the default controller
            w0 = limit.guess_from_trajectory(pb.full, traj, pb.x0) if traj is not None else None
        if w0 is None:
            w0 = limit.straight_guess(pb.full, pb.targets.route, pb.x0)
        guess_cpu.append(cpu_time() - c0)
        problems.append(pb)
        if i == 0:  # warm-up: builds both solvers once
            for s in SOLVERS:
                _timed(pb, w0, s)
        for s in SOLVERS:
            cold[s].append(_timed(pb, w0, s))
        print(i, *(f"{s}: {cold[s][-1]['status']} {cold[s][-1]['f']:.5f} "
                   f"{cold[s][-1]['it']} it {cold[s][-1]['cpu']:.1f} s" for s in SOLVERS),
              flush=True)
    cross = cross_check(problems, cold)
    warm: dict[str, list[dict]] = {s: [] for s in SOLVERS
                                   if s not in ("ipopt-stage", "ipopt-monotone")}
    for s in warm:
        ok = [i for i, r in enumerate(cold[s]) if r["ok"]]
        for i in ok:
            near = nearest(i, ok, unit)
            if not near:
                break
            j = near[0]
            ws = cold[s][j]["point"]
            warm[s].append(_timed(problems[i], ws.w, s, warm=ws) | {"frame": i})
    near = near_solves(template, thetas, cold, args, track, options)
    both = [i for i in range(args.n) if "fatrop" in cold and cold["ipopt"][i]["ok"]
            and cold["fatrop"][i]["ok"]]
    rel = np.array([abs(cold["fatrop"][i]["f"] - cold["ipopt"][i]["f"]) / cold["ipopt"][i]["f"]
                    for i in both])
    lines = ["# Limit-lap NLP: IPOPT and fatrop side by side", "", markdown(), "",
             f"Command: `python benchmarks/bench_limitlap_solvers.py --n {args.n} --seed "
             f"{args.seed} --template {args.template} --solvers {args.solvers} --cold-start "
             f"{args.cold_start}{''.join(' --ipopt-option ' + o for o in args.ipopt_option)}` "
             f"(paper track, "
             f"40 intervals per leg, one core; CPU = process time; decision variables "
             f"{', '.join(keys)}).", "",
             "| solve | converged | iterations (median) | CPU median (s) | CPU max (s) | "
             "CPU per iteration, median (ms) |", "|---|---|---|---|---|---|"]
    for s in SOLVERS:
        lines += _row(f"{s}, cold ({args.cold_start} guess)", cold[s])
    for s in SOLVERS:
        if warm.get(s):
            lines += _row(f"{s}, warm (nearest neighbour's solution)", warm[s])
    for s, runs in near.items():
        if runs:
            lines += _row(f"{s}, near (own solution, θ moved by {100 * args.near:g} % of the "
                          "range)", runs)
    lines += ["", f"The cold guess's own CPU per frame ({args.cold_start}; the first frame's "
              f"includes building its NLP): median {np.median(guess_cpu):.2f} s, max "
              f"{np.max(guess_cpu):.2f} s."]
    if len(rel):
        lines += ["", f"Same start, both converged ({len(both)} frames): |fatrop − IPOPT| / "
                  f"IPOPT lap median {100 * np.median(rel):.4f} %, max {100 * rel.max():.4f} %; "
                  f"within 0.01 %: {int(np.sum(rel <= 1e-4))}/{len(both)}."]
    for s in SOLVERS:
        if s not in ("ipopt", "fatrop"):
            pairs = [(cold[s][i]["f"], cold["ipopt"][i]["f"]) for i in range(args.n)
                     if cold[s][i]["ok"] and cold["ipopt"][i]["ok"]]
            rel_s = np.array([abs(a - b) / b for a, b in pairs])
            lines += ["", f"Same start, {s} against IPOPT ({len(rel_s)} frames): "
                      f"{_pct(rel_s)}."]
    lines += _cross_lines(cross, cold)
    lines += _agreement(near, "near")
    fails = [f"frame {i}: {cold['fatrop'][i]['status']}" for i in range(args.n)
             if "fatrop" in cold and not cold["fatrop"][i]["ok"]]
    if fails:
        lines += ["", "fatrop cold failures: " + "; ".join(fails) + "."]
    text = "\n".join(lines) + "\n"
    if "fatrop" in cold:  # the summary row compares the two solvers
        text = with_summary(text, [summary_row(cold, warm, args.n, args.cold_start)])
    args.out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
