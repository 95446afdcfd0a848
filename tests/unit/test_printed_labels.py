"""What the commands print says what each figure is: CPU and wall time each for what they
measure, no negative zero, every column defined where it is read, one track's co-design lap as
a lap, and a plain sentence of what holds a co-design frame."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest

from casadrone.cli import app

ROOT = Path(__file__).resolve().parents[2]

#: A printed negative zero: "-0", "-0.000" (not "-0.575", not "-0.0001").
NEGATIVE_ZERO = re.compile(r"-0(?:\.0+)?(?![\d.eE])")


def test_the_negative_zero_pattern():
    assert NEGATIVE_ZERO.search("  1   -0.0000   0.000 / -0.000")
    assert not NEGATIVE_ZERO.search("0.0456  0.401 / -0.575  -0.0001 -0.0101 RL-RR 1e-05")


# --- trim --solver all: the solve's CPU, its set-up apart ----------------------------------------

def test_trim_times_the_solve_apart_from_its_one_off_set_up():
    import importlib

    from casadrone.airframe import build_airframe
    from casadrone.config.airframe import load_airframe

    trim_mod = importlib.import_module("casadrone.trim")
    frame = build_airframe(load_airframe("HS210", []))
    trim_mod.trim(frame, "forward", 20.0, "ipopt")  # one-off imports and model builds paid
    trim_mod._ipopt.cache_clear()  # the set-up (building the IPOPT solver) not yet done
    first = trim_mod.trim(frame, "forward", 20.0, "ipopt")
    second = trim_mod.trim(frame, "forward", 20.0, "ipopt")
    # building nlpsol costs more CPU than the 3-iteration solve; done once, it costs nothing
    assert first.setup_cpu_s > first.cpu_time_s > 0
    assert second.setup_cpu_s < first.setup_cpu_s / 10
    # the solve's own cost does not carry the set-up: the first solve is no dearer than the
    # second by the set-up's amount
    assert first.cpu_time_s < second.cpu_time_s + first.setup_cpu_s / 2


def test_trim_all_prints_cpu_of_the_solve_and_the_set_up_apart(cli_runner):
    r = cli_runner.invoke(app, ["trim", "HS210", "--condition", "forward", "--speed", "20",
                                "--solver", "all"])
    assert r.exit_code == 0, r.output
    header = next(line for line in r.stdout.splitlines() if line.startswith("solver"))
    assert "CPU (ms)" in header and "time (s)" not in header
    legend = r.stdout.split("CPU (ms): ", 1)[1].splitlines()
    assert "CPU time of the solve alone" in legend[0] and "set-up" in legend[0]
    assert all(f"{s} " in legend[1] for s in ("ipopt", "nelder-mead", "newton"))
    assert not NEGATIVE_ZERO.search(r.stdout)
    # the forward trim is a real problem for every solver (not the hover guess): iterations > 0
    rows = [line.split() for line in r.stdout.splitlines()
            if line.split()[:1] in (["ipopt"], ["nelder-mead"], ["newton"]) and "yes" in line]
    assert len(rows) == 3 and all(int(row[3]) > 0 for row in rows)


# --- simulate: no negative zero, the columns defined ------------------------------------------

def test_simulate_prints_no_negative_zero_and_defines_pair_thrust(cli_runner):
    r = cli_runner.invoke(app, ["simulate", "SY250"])
    assert r.exit_code == 0, r.output
    assert not NEGATIVE_ZERO.search(r.stdout), r.stdout
    assert "pair thrust max/min (N)" in r.stdout  # the column ...
    assert "pair thrust = max/min over the interval of (T_FL + T_RL) - (T_FR + T_RR)" in r.stdout
    assert "effort = mean roll-effort voltage" in r.stdout  # ... and both its legend lines


@pytest.mark.parametrize("args", [["linearise", "SY250"], ["massprops", "SY250-components"]])
def test_other_tables_print_no_negative_zero(cli_runner, args):
    # the hover Jacobians hold exact zeros that CasADi computes as -0.0 (printed "-0" before)
    r = cli_runner.invoke(app, args)
    assert r.exit_code == 0, r.output
    assert not NEGATIVE_ZERO.search(r.stdout), r.stdout


def test_simulate_text_of_values_below_the_last_digit():
    from casadrone.cli.flight import _simulate_text

    r = {"airframe": "X", "track": "t", "controller": "c", "integrator": "rk4",
         "status": "completed", "wall_time_s": 0.1, "indices": {"J3": 16.6, "J5": -1e-9},
         "intervals": [{"waypoint": 1, "split_time_s": 9.5, "effort_V": -3e-7,
                        "pair_thrust_max_N": 1e-6, "pair_thrust_min_N": -2e-6}]}
    text = _simulate_text(r)
    assert not NEGATIVE_ZERO.search(text), text


# --- limit-lap: one solve's iterations, the whole lap's CPU and wall ---------------------------

def test_limit_lap_text_names_what_each_figure_measures():
    from casadrone.cli.limit import _text

    r = {"status": "completed", "lap_time_s": 3.88, "point_mass_reference_s": 3.5,
         "start": "closed-loop", "certainty": "agreed", "iterations": 59,
         "wall_time_s": 1639.5, "cpu_time_s": 110.25, "split_times_s": [1.0, 2.0],
         "lap_times_s": [3.88], "bang_bang_fraction": 0.5, "resimulation_miss_m": 0.01,
         "top_speed_m_s": 20.0, "max_advance_ratio": math.nan, "sensitivities": {},
         "ending": "optimal", "return_status": "Solve_Succeeded",
         "starts": [{"start": "closed-loop", "ending": "optimal", "success": True,
                     "lap_time_s": 3.88, "return_status": "Solve_Succeeded"}]}
    first, cost = _text("SY250", "paper-rectangle", r).splitlines()[:2]
    assert "iterations" not in first and "wall" not in first
    assert "chosen start's took 59 iterations" in cost
    assert "CPU 110.2 s, wall 1639.5 s" in cost  # each named, from the same span
    failed = _text("SY250", "t", {"status": "failed", "reason": "r", "wall_time_s": 2.0,
                                  "cpu_time_s": 1.0})
    assert "CPU 1.0 s, wall 2.0 s" in failed


def test_limit_lap_measures_its_cpu():
    from casadrone.airframe import build_airframe
    from casadrone.config.airframe import load_airframe
    from casadrone.config.io import load
    from casadrone.config.track import DEFAULT_TRACK, TrackConfig
    from casadrone.limit.lap import LimitLapOptions, limit_lap

    frame = build_airframe(load_airframe("SY250", []))
    lap = limit_lap(frame, load(TrackConfig, DEFAULT_TRACK), LimitLapOptions(starts=()))
    assert lap.status == "failed" and "no start" in lap.reason  # refused at once: fast
    assert lap.cpu_time_s > 0 and "cpu_time_s" in lap.as_dict()


# --- codesign: one track's lap, the sentence of what holds the frame ------------------------

def test_codesign_headline_of_one_track_is_its_lap():
    from casadrone.cli.codesign import objective_text

    assert objective_text(3.83, "sum", {"paper-rectangle": 3.83}) == \
        "lap 3.8300 s on paper-rectangle"
    two = objective_text(7.5, "sum", {"a": 3.5, "b": 4.0})
    assert two == "objective 7.5000 s (sum of 2 tracks; a 3.5000 s, b 4.0000 s)"


def _paper_certificate():
    """The certificate of the paper co-design (codesign-paper, 40 intervals per leg), as the
    command stored it: benchmarks/codesign-paper-40.json."""
    from casadrone.codesign.certificate import Certificate, VariableCheck

    data = json.loads((ROOT / "benchmarks" / "codesign-paper-40.json").read_text())
    c = data["certificate"]
    return Certificate((), tuple(VariableCheck(**v) for v in c["variables"]),
                       c["active_constraints"], c["passed"], c["reason"])


def test_why_sentence_of_the_paper_co_design():
    # The paper optimum (real active set): both arm lengths at their lower bound 100 mm with
    # positive multipliers, the RL-RR propeller gap active, α interior with no row on it.
    # With λb = 100 mm the rear rotors lie 2 λb sin(β/2) apart; the gap row is active when that
    # is one propeller diameter (127 mm, SY250-components), so β = 2 asin(127 / 200) = 78.84°.
    cert = _paper_certificate()
    why = cert.why
    assert why.startswith("both arms want to be shorter than the 100 mm bound; ")
    beta = float(re.search(r"the rear props' clearance sets β = ([\d.]+)°", why).group(1))
    assert beta == pytest.approx(math.degrees(2 * math.asin(127.0 / 200.0)), abs=0.005)
    assert re.search(r"the lap itself sets α = [\d.]+°\.$", why)
    assert "λa" not in why and "λb" not in why  # the arms are named by the bound clause
    text = cert.text()
    assert text.splitlines()[1] == f"  why: {why}"  # the why block opens with the sentence
    assert cert.as_dict()["why"] == why


def test_why_sentence_of_other_active_sets():
    from casadrone.codesign.certificate import VariableCheck, why_sentence

    def var(key, value, state, multiplier):
        return VariableCheck(key, value, state, 0.0, 0.0, multiplier, True)

    # an upper bound that pushes, one that holds nothing, the front gap setting both front keys
    why = why_sentence([var("lambda_a_mm", 120.0, "interior", 0.0),
                        var("alpha_deg", 70.0, "interior", 0.0),
                        var("lambda_b_mm", 150.0, "upper", 0.02),
                        var("beta_deg", 90.0, "upper", 0.0)],
                       {"gap FR-FL": -0.01, "hover": -0.2})
    assert why == ("the rear arms want to be longer than the 150 mm bound; the rear arm angle "
                   "rests at the 90.00° bound; the front props' clearance sets λa = 120 mm and "
                   "α = 70.00°; the hover limit (the weight four rotors can lift) is active.")
