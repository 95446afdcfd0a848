"""Benchmark (expensive): do the limit lap's reported sensitivities hold against finite
differences of the certified laps?

For each ``--frames`` airframe on the paper track: the ``--certify`` limit lap at the frame
(every cold start and grid rounds, casadrone.limit.search) gives dT/dθ of each key per 1 % of
its Table 1 range, with its uncertainty over the call's verified optima or "not resolved"
(casadrone.limit.sensitivity); then the ``--certify`` laps at θ ± 2 % of the key's range give
the central finite difference (T₊ − T₋) / 4 per 1 %. A resolved slope passes when the finite
difference lies within its stated uncertainty of it; an unresolved one passes by saying so.
Each lap is one ``limit_lap`` call in this process (one core), appended to the log as it ends, so
a run can be stopped and resumed (``--log``; laps already in it are not solved again).

Run: ``python benchmarks/bench_limitlap_sensitivity_fd.py --frames SY250 HS210`` (writes
``benchmarks/RESULTS-limitlap-sensitivity-fd.md``, ``--out``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.machine import cpu_time, describe, markdown, with_summary  # noqa: E402

HERE = Path(__file__).resolve().parent
KEYS = ("lambda_a_mm", "lambda_b_mm", "alpha_deg", "beta_deg")
#: The finite difference's step, as a share of the key's Table 1 range (issue 43: ±2 %).
STEP = 0.02


def certified(frame: str, overrides: list[str]) -> dict:
    """The --certify limit lap of ``frame`` with ``overrides`` on the paper track."""
    from casadrone.config.airframe import load_airframe
    from casadrone.config.io import load
    from casadrone.config.track import TrackConfig
    from casadrone.evaluate import DEFAULT_TRACK
    from casadrone.limit.lap import LimitLapOptions, design_limit_lap
    from casadrone.limit.search import search_options

    options = search_options("certify", LimitLapOptions(), periodic=False)
    c0 = cpu_time()
    lap = design_limit_lap(load_airframe(frame, overrides), load(TrackConfig, DEFAULT_TRACK),
                                  options)
    return {"frame": frame, "overrides": overrides, "status": lap.status,
            "lap_time_s": lap.lap_time_s, "start": lap.start, "certainty": lap.certainty,
            "spread_s": lap.spread_s, "cpu_s": cpu_time() - c0,
            "table": [t.as_dict() for t in lap.sensitivity_table]}


def moves(frame: str) -> dict[str, list[str]]:
    """The overrides of each lap the check needs: the frame itself and ± STEP of each key."""
    from casadrone.config.airframe import TABLE1_BOUNDS, load_airframe

    cfg = load_airframe(frame)
    out: dict[str, list[str]] = {"centre": []}
    for key in KEYS:
        lo, hi = TABLE1_BOUNDS[key]
        v = float(getattr(cfg, key))
        for sign, tag in ((1, "+"), (-1, "-")):
            out[f"{key}{tag}"] = [f"{key}={v + sign * STEP * (hi - lo):.10g}"]
    return out


def check(frame: str, laps: dict[str, dict]) -> list[dict]:
    """Per key: the reported slope and uncertainty (ms per 1 %), the finite difference, and
    whether it holds."""
    centre = laps["centre"]
    rows = []
    for t in centre["table"]:
        if t["key"] not in KEYS:
            continue
        hi, lo = laps.get(f"{t['key']}+"), laps.get(f"{t['key']}-")
        fd = math.nan if hi is None or lo is None else \
            (hi["lap_time_s"] - lo["lap_time_s"]) / (2 * 100 * STEP)
        value, unc = t["s_per_percent"], t["uncertainty_s_per_percent"]
        # None: resolved, but its finite difference not run
        holds = True if not t["resolved"] else \
            None if not math.isfinite(fd) else bool(abs(fd - value) <= unc)
        rows.append({"frame": frame, "key": t["key"], "value_ms": 1e3 * value,
                     "uncertainty_ms": 1e3 * unc, "resolved": t["resolved"],
                     "optima": t["optima"], "fd_ms": 1e3 * fd, "holds": holds,
                     "laps": (lo and lo["lap_time_s"], hi and hi["lap_time_s"]),
                     "starts": (lo and lo["start"], hi and hi["start"])})
    return rows


VERDICT = {True: "yes", False: "NO", None: "not run"}


def fmt(v: float) -> str:
    return f"{v:+.4f}" if math.isfinite(v) else "–"


def report(log: Path, out: Path, frames: list[str], cmd: str) -> None:
    entries = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
    rows, centres = [], []
    for frame in frames:
        laps = {e["tag"]: e for e in entries if e["frame"] == frame}
        if "centre" in laps:
            centres.append(laps["centre"])
            rows += check(frame, laps)
    lines = ["# Limit lap: sensitivities against finite differences of the certified laps", "",
             f"## What was measured ({describe()['date'][:10]})", "",
             f"- {sum(r['holds'] is True for r in rows)} of {len(rows)} slopes hold (resolved: the "
             "finite difference within the stated uncertainty; or reported not resolved); "
             f"{sum(math.isfinite(r['fd_ms']) for r in rows)} of {len(rows)} finite "
             "differences solved (the others' laps are not in the log: not run).",
             f"- Command: `{cmd}`", "", markdown(), "",
             "Slopes in ms per 1 % of the key's paper Table 1 range (λ: 0.5 mm, α and β: "
             "0.25°); finite difference (T(θ + 2 %) − T(θ − 2 %)) / 4 of the `--certify` laps.",
             "", "| frame | key | reported (ms/%) | uncertainty (ms/%) | resolved | optima | "
             "finite difference (ms/%) | holds | laps at −2 % / +2 % (s) | their starts |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lo, hi = r["laps"]
        lines.append(f"| {r['frame']} | {r['key']} | {r['value_ms']:+.4f} | "
                     f"{r['uncertainty_ms']:.4f} | {'yes' if r['resolved'] else 'not resolved'}"
                     f" | {r['optima']} | {fmt(r['fd_ms'])} | {VERDICT[r['holds']]} | "
                     f"{'not run' if lo is None else f'{lo:.4f}'} / "
                     f"{'not run' if hi is None else f'{hi:.4f}'} | {r['starts'][0] or '–'} / "
                     f"{r['starts'][1] or '–'} |")
    lines += ["", "The certified laps at the frames:", ""]
    lines += [f"- {c['frame']}: {c['lap_time_s']:.4f} s from {c['start']} ({c['certainty']}, "
              f"spread {c['spread_s']:.4f} s), {c['cpu_s']:.0f} s CPU" for c in centres]
    held = sum(r["holds"] is True for r in rows)
    summary_rows = [(
        "limit-lap sensitivities dT/dλa, dT/dλb, dT/dα, dT/dβ against finite differences "
        "(±2 % of the Table 1 range) of the --certify laps",
        f"{held} of {len(rows)} hold; " + "; ".join(
            f"{r['frame']} {r['key']} {r['value_ms']:+.3f} ± {r['uncertainty_ms']:.3f} ms/% "
            f"({'resolved' if r['resolved'] else 'not resolved'})" for r in rows),
        f"`{cmd}`")]
    out.write_text(with_summary("\n".join(lines) + "\n", summary_rows), encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", nargs="+", default=["SY250", "HS210"])
    ap.add_argument("--log", type=Path, default=HERE / "limitlap-sensitivity-fd.jsonl")
    ap.add_argument("--out", type=Path, default=HERE / "RESULTS-limitlap-sensitivity-fd.md")
    ap.add_argument("--report", action="store_true", help="only rewrite --out from --log")
    ap.add_argument("--tags", nargs="*", default=[],
                    help="only these laps (centre, KEY+ or KEY-), e.g. lambda_a_mm+")
    args = ap.parse_args(argv)
    done = set()
    if args.log.exists():
        done = {(e["frame"], e["tag"]) for e in
                (json.loads(line) for line in args.log.read_text().splitlines() if line.strip())}
    if not args.report:
        for frame in args.frames:
            for tag, overrides in moves(frame).items():
                if (frame, tag) in done or (args.tags and tag not in args.tags):
                    continue
                entry = certified(frame, overrides) | {"tag": tag}
                print(json.dumps(entry), flush=True)
                with args.log.open("a", encoding="utf-8") as f:
                    f.write(json.dumps(entry) + "\n")
    cmd = "python benchmarks/bench_limitlap_sensitivity_fd.py --frames " + " ".join(args.frames)
    report(args.log, args.out, args.frames, cmd)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
