"""casadrone build without a solve: combinations, refusals before any solve (each checked against
a hand-worked figure), the problem's refusals in one line, the bill of materials against the
catalogue's rows and the URDF read by a second parser."""

from __future__ import annotations

import csv
import itertools
import math
import xml.etree.ElementTree as ET
from dataclasses import replace

import numpy as np
import pytest
from typer.testing import CliRunner

from casadrone.airframe import build_airframe
from casadrone.build.checks import load_build_problem
from casadrone.build.combos import Combination, combination_airframe, combinations, refusal
from casadrone.cli import app
from casadrone.codesign.checks import template_of
from casadrone.config.io import DATA_DIR, ConfigError
from casadrone.export import export
from casadrone.export.bom import bom_lines
from casadrone.export.source import ExportSource
from casadrone.parts import shipped_catalogue

SMALL = DATA_DIR / "problems" / "build-small.yaml"
KEYS = ("lambda_a_mm", "lambda_b_mm")
LOWER, UPPER = np.array([100.0, 100.0]), np.array([150.0, 150.0])
#: ISA sea-level speed of sound (m/s) and air density (kg/m³), typed in.
SOUND_M_S, RHO = 340.3, 1.225


@pytest.fixture(scope="module")
def problem():
    return load_build_problem(SMALL)


def combo(prop: str, motor: str, pack: str) -> Combination:
    cat = shipped_catalogue()
    return Combination(cat.get(prop, "propeller"), cat.get(motor, "motor"), cat.get(pack, "pack"))


def test_build_small_enumerates_three_by_three_by_three(problem):
    combos = combinations(shipped_catalogue(), problem.build)
    assert len(combos) == 27
    assert len({c.label for c in combos}) == 27


def test_tip_speed_refusal_matches_the_hand_worked_mach_number(problem):
    """2550 KV on a full 6S pack (6 × 4.2 V ≈ 25 V) spins a 5-inch propeller's tips past Mach 1;
    1750 KV on the same pack stays below 0.9: K_V V π D / 60 / a."""
    c = combo("uiuc-da4022-5x3.75-3blade", "tmotor-velox-v2207-v2-2550kv",
              "cnhl-black-v2-1300mah-6s")
    mach = 2550 * c.pack.full_voltage_v * math.pi * 0.127 / 60 / SOUND_M_S
    assert 24.0 < c.pack.full_voltage_v < 25.3  # 6 cells, 4.0-4.2 V each
    assert mach > 1.1
    why = refusal(template_of(problem), c, problem.build, KEYS, LOWER, UPPER)
    assert why.startswith(f"tip Mach {mach:.2f}")
    slow = combo("uiuc-da4022-5x3.75-3blade", "tmotor-velox-v2207-v2-1750kv",
                 "cnhl-black-v2-1300mah-6s")
    assert 1750 * slow.pack.full_voltage_v * math.pi * 0.127 / 60 / SOUND_M_S < 0.9
    assert refusal(template_of(problem), slow, problem.build, KEYS, LOWER, UPPER) == ""


def test_a_propeller_too_weak_to_lift_the_frame_is_refused(problem):
    """C_T0 so small that even at the motor's no-load speed (K_V V_full, which no loaded rotor
    reaches) four rotors lift less than the pack and motors alone weigh."""
    c = combo("uiuc-da4022-5x3.75-3blade", "tmotor-velox-v2207-v2-1750kv",
              "cnhl-ministar-650mah-4s")
    n_max = 1750 * c.pack.full_voltage_v / 60  # rev/s
    parts_weight = (c.pack.mass_kg + 4 * c.motor.mass_kg) * 9.81
    ct0 = 0.5 * parts_weight / (4 * RHO * n_max**2 * 0.127**4)  # half of what would lift them
    weak = replace(c, propeller=replace(c.propeller, ct_coefficients=(ct0, 0.0, 0.0)))
    why = refusal(template_of(problem), weak, problem.build, KEYS, LOWER, UPPER)
    assert "cannot hover" in why or ("thrust-to-weight" in why and "< 1" in why)


def test_a_propeller_wider_than_any_frame_of_the_box_is_refused(problem):
    """A 10-inch propeller: at the box's largest X frame (λ = 150 mm, 90°) neighbouring rotors
    are √2 · 150 = 212 mm apart, less than its 254 mm."""
    c = combo("uiuc-da4022-5x3.75-3blade", "tmotor-velox-v2207-v2-1750kv",
              "cnhl-ministar-650mah-4s")
    big = replace(c, propeller=replace(c.propeller, diameter_m=0.254))
    assert math.sqrt(2) * 150 < 254
    why = refusal(template_of(problem), big, problem.build, KEYS, LOWER, UPPER)
    assert why.startswith("propeller diameter 254 mm")


def test_the_combination_airframe_carries_the_parts_masses_and_pack(problem):
    """The build's mass: the template's frame plus the parts' (motor 35.1 g and pack 151 g as
    in the catalogue's rows); the pack's energy model and the motor's current limit set."""
    c = combo("uiuc-da4022-5x3.75-3blade", "tmotor-velox-v2207-v2-1750kv",
              "cnhl-black-v2-1300mah-4s")
    cfg = combination_airframe(template_of(problem), c, 0.004)
    assert cfg.components.motor_mass_kg == pytest.approx(0.0351 + 0.004)
    assert cfg.components.battery_mass_kg == pytest.approx(0.151)
    b = cfg.propulsion.battery
    assert (b.capacity_ah, b.c_rating, b.cells) == (1.3, 130, 4)
    assert cfg.propulsion.motor.max_current_a == pytest.approx(36.6)
    template = build_airframe(template_of(problem)).mass
    heavier = 4 * (0.0351 + 0.004 - 0.030) + (0.151 - 0.080)  # against the template's parts
    assert build_airframe(cfg).mass == pytest.approx(template + heavier, abs=1e-9)


def test_bill_of_materials_adds_up_to_the_urdf_mass(problem):
    """The bill's lines: 4 motors of the catalogue's 35.1 g, the pack's 151 g; its total the
    mass of the URDF's links (read by ElementTree)."""
    c = combo("uiuc-da4022-5x3.75-3blade", "tmotor-velox-v2207-v2-1750kv",
              "cnhl-black-v2-1300mah-4s")
    cfg = combination_airframe(template_of(problem), c, 0.004)
    src = ExportSource(cfg, build_airframe(cfg), "test", "-")
    lines = {b.item: b for b in bom_lines(src)}
    assert lines["motor"].quantity == 4 and lines["motor"].unit_mass_g == pytest.approx(35.1)
    assert lines["motor"].part == "tmotor-velox-v2207-v2-1750kv"
    assert lines["pack"].unit_mass_g == pytest.approx(151.0)
    assert lines["propeller"].unit_mass_g == pytest.approx(4.0)
    total = sum(b.mass_g for b in lines.values())
    root = ET.fromstring(export(src, "urdf"))
    urdf_g = 1000 * sum(float(m.get("value")) for m in root.iter("mass"))
    assert total == pytest.approx(urdf_g, rel=1e-6)
    table = [line for line in export(src, "bom-csv").splitlines() if not line.startswith("#")]
    assert table[0].startswith("item,quantity") and table[-1].startswith("total")


def cli(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


@pytest.mark.parametrize(("override", "key", "words"), [
    ("build.propellers=[uiuc-nope]", "build.propellers.0", "no propeller named 'uiuc-nope'"),
    ("build.packs=[tmotor-velox-v2207-v2-1750kv]", "build.packs.0", "no pack named"),
    ("airframe=configs/airframes/SY250-components.yaml", "airframe", "propeller kind"),
])
def test_bad_problems_exit_2_in_one_line_naming_file_and_key(override, key, words, tmp_path):
    result = cli("build", SMALL, override, "--out", tmp_path / "out")
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"{SMALL}: {key}: ") and words in lines[0]
    assert not (tmp_path / "out").exists()  # nothing written


def test_a_used_out_folder_is_refused_before_any_work(tmp_path):
    (tmp_path / "x").write_text("")
    result = cli("build", SMALL, "--out", tmp_path)
    assert result.exit_code == 2 and result.stderr.startswith("--out: ")


def test_the_loader_raises_one_line_per_problem():
    with pytest.raises(ConfigError) as info:
        load_build_problem(SMALL, ["build.motors=[a-motor, tmotor-velox-v2207-v2-1750kv]"])
    assert len(info.value.lines) == 1 and "build.motors.0" in info.value.lines[0]


def test_a_bill_of_an_airframe_without_parts_is_the_airframe_whole():
    """SY250 gives its mass as one figure (mass_kg: 0.32 in SY250.yaml): one line of 320 g."""
    result = cli("export", "SY250", "--format", "bom-csv")
    assert result.exit_code == 0, result.output
    rows = list(csv.reader(line for line in result.stdout.splitlines()
                           if line and not line.startswith("#")))
    assert rows[0][:4] == ["item", "quantity", "unit_mass_g", "mass_g"]
    assert [r[3] for r in rows[1:]] == ["320.0", "320.0"]  # the airframe, the total


def _square(x: int) -> int:
    return x * x


@pytest.mark.parametrize("backend", [
    {"name": "serial"},
    pytest.param({"name": "processes", "workers": 2}, marks=pytest.mark.slow),
    pytest.param({"name": "dask", "workers": 2}, marks=pytest.mark.slow),
])
def test_every_pool_returns_every_task_once(backend):
    """The build's pool on each backend: every submitted task's result comes back once, however
    the tasks finish."""
    from casadrone.build.pool import Pool
    from casadrone.config.problem import BackendConfig

    pool = Pool(BackendConfig(**backend))
    try:
        running = [pool.submit(_square, k) for k in range(5)]
        got = []
        while running:
            done = pool.first_done(running)
            assert done
            running = [f for f in running if f not in done]
            got += [f.result() for f in done]
    finally:
        pool.close()
    assert sorted(got) == [0, 1, 4, 9, 16]


def _raced(label_combo: Combination, race_s: float, mass_kg: float = 0.5,
           left_wh: float = 5.0, bound_s: float = math.nan):
    from casadrone.build.solve import BuildResult

    return BuildResult(label_combo, "raced", race_s=race_s, feasible=True, mass_kg=mass_kg,
                       energy_left_wh=left_wh, bound_s=bound_s)


def test_branch_and_bound_prunes_above_the_rank_th_race_and_keeps_the_rest(problem,
                                                                          monkeypatch):
    """A stand-in co-design whose race is 1.1 x the bound: with rank 1, bounds 1.0 and 1.05 are
    co-designed (1.05 < 1.1, the best race when it is reached), 2.0 and 3.0 pruned."""
    from casadrone.build import search
    from casadrone.build.pool import Pool
    from casadrone.config.problem import BackendConfig

    combos = combinations(shipped_catalogue(), problem.build)[:4]
    monkeypatch.setattr(search, "evaluate",
                        lambda prob, c, laps, bound, seeds, start, soc:
                        _raced(c, 1.1 * bound, bound_s=bound))
    order = list(zip([1.0, 1.05, 2.0, 3.0], combos, strict=True))
    strict = problem.model_copy(update={"build": problem.build.model_copy(update={"rank": 1})})
    results = search.branch_and_bound(strict, order, None, Pool(BackendConfig()))
    outcome = {r.combination.label: r.outcome for r in results}
    assert [outcome[c.label] for c in combos] == ["raced", "raced", "pruned", "pruned"]
    assert search.ranking(results, 1)[0].race_s == pytest.approx(1.1)


def test_fronts_keep_the_builds_no_other_beats_in_both():
    """Race 1, 2, 3 s with masses 0.6, 0.5, 0.55 kg: the 3 s build is heavier than the 2 s one,
    so it is off the mass front; energy left 1, 3, 2 Wh: the same."""
    from casadrone.build.search import front

    combos = combinations(shipped_catalogue(), load_build_problem(SMALL).build)[:3]
    rs = (_raced(combos[0], 1.0, 0.60, 1.0), _raced(combos[1], 2.0, 0.50, 3.0),
          _raced(combos[2], 3.0, 0.55, 2.0))
    assert front(rs, lambda r: r.mass_kg) == [combos[0].label, combos[1].label]
    assert front(rs, lambda r: -r.energy_left_wh) == [combos[0].label, combos[1].label]


def test_a_build_resumes_from_its_folder_and_refuses_another_problems(tmp_path, monkeypatch):
    """A stopped build's folder: the results it holds are read back whole and neither bounded
    nor solved again; the others are. A folder of another problem is refused (exit 2, one line),
    nothing in it touched."""
    import casadrone.build.search as search
    from casadrone.build import resume
    from casadrone.build.solve import BuildResult

    problem = load_build_problem(SMALL, ["backend.name=serial", "build.certify=false"])
    kept, _ = search.screened(problem)
    solved, bounded = [], []

    def fake_solve(problem, combo, laps, bound_s=math.nan, seeds=None, start=None, soc=None):
        solved.append(combo.label)
        return BuildResult(combo, "raced", race_s=10.0 + len(solved), bound_s=bound_s,
                           feasible=True)

    def fake_bound(problem, combo, laps, near=None):
        bounded.append(combo.label)
        return 1.0, None
    monkeypatch.setattr(search, "evaluate", fake_solve)
    monkeypatch.setattr(search, "bound_and_solution", fake_bound)
    out = tmp_path / "b"
    resume.begin(out, problem, None)
    first = BuildResult(kept[0], "raced", race_s=5.0, feasible=True, theta={"lambda_a_mm": 120.0})
    resume.keep(out, first)  # the stop came after one combination
    held = resume.held(out)
    assert [(r.label, r.race_s, r.theta) for r in held] == [(first.label, 5.0, first.theta)]
    result = search.build(problem, None, lambda r: resume.keep(out, r), held)
    assert kept[0].label not in solved + bounded
    assert sorted(solved) == sorted(c.label for c in kept[1:])
    assert result.resumed == 1 and result.winner == kept[0].label
    assert len(resume.held(out)) == len(result.results)  # every result on disk, once
    assert resume.folder_problem(out, problem, None) is None
    other = load_build_problem(SMALL, ["build.rank=5"])
    assert "another problem" in resume.folder_problem(out, other, None)
    assert "another problem" in resume.folder_problem(out, problem, 3)
    before = sorted(p.name for p in out.rglob("*"))
    cli_result = cli("build", SMALL, "build.rank=5", "--out", out)
    assert cli_result.exit_code == 2 and len(cli_result.stderr.splitlines()) == 1
    assert cli_result.stderr.startswith(f"--out: {out}: holds a build of another problem")
    assert sorted(p.name for p in out.rglob("*")) == before


def test_a_combination_starts_from_its_nearest_raced_neighbour():
    """Continuation across the catalogue: a raced combination with the same propeller and motor
    starts the next, else one with the same propeller, else the latest raced; none before the
    first race, and a result without a race (failed, pruned) never."""
    from casadrone.build.search import neighbour
    from casadrone.build.solve import BuildResult

    combos = combinations(shipped_catalogue(), load_build_problem(SMALL).build)
    target = combos[0]
    same_prop = next(c for c in combos if c.propeller == target.propeller
                     and c.motor != target.motor)
    same_both = next(c for c in combos[1:] if c.propeller == target.propeller
                     and c.motor == target.motor)
    other = next(c for c in combos if c.propeller != target.propeller)

    def raced(c, lap):
        return BuildResult(c, "raced", race_lap=lap)

    def near(done):
        got = neighbour(target, done)
        return None if got is None else got.race_lap
    assert near([]) is None
    assert near([BuildResult(same_both, "failed")]) is None
    assert near([raced(other, "o1"), raced(other, "o2")]) == "o2"
    assert near([raced(same_prop, "p"), raced(other, "o")]) == "p"
    assert near([raced(same_both, "b"), raced(same_prop, "p"), raced(other, "o")]) == "b"


def test_bounds_walk_the_catalogue_one_part_at_a_time(problem):
    """The order the bounds are solved in (each from the one before: search.snake) visits
    every combination of build-small once, consecutive ones differing in exactly one part, and
    with some refused (6S with two of the motors) still differing in one or two; the plain
    catalogue order jumps from a 6S pack back to a 650 mAh one at every motor."""
    from casadrone.build.search import screened, snake

    every = list(combinations(shipped_catalogue(), problem.build))
    walk = snake(every)
    assert sorted(c.label for c in walk) == sorted(c.label for c in every)

    def changed(a, b):
        return sum(getattr(a, k).name != getattr(b, k).name
                   for k in ("propeller", "motor", "pack"))

    assert all(changed(a, b) == 1 for a, b in itertools.pairwise(walk))
    assert any(changed(a, b) == 2 for a, b in itertools.pairwise(every))  # the catalogue's order
    kept = snake(screened(problem)[0])
    assert max(changed(a, b) for a, b in itertools.pairwise(kept)) <= 2


def test_a_race_from_the_shipped_lap_alone_falls_back_on_the_point_mass_start(problem):
    """build-small starts every lap from the shipped lap alone; a race of several laps has
    none shipped, so the build's lap options solve the point-mass start where the shipped lap
    gives none (and only there: a problem that names its starts keeps them)."""
    from casadrone.build.solve import lap_options

    template = template_of(problem)
    assert tuple(lap_options(problem, template).starts) == ("library",)
    assert lap_options(problem, template).fallback_starts == ("point-mass",)
    named = load_build_problem(SMALL, ["limit_lap.starts=[library, coarse-grid]"])
    assert lap_options(named, template_of(named)).fallback_starts == ()
