"""The parts catalogue (casadrone.parts, casadrone.config.parts, ``casadrone parts``): its files
read by a second parser, every row cited, the propeller fits against an independent solve and
hand-worked numbers of the raw file, physical ranges of the motors and packs, conversion into
airframe sections, and the user file refused where no real part could be."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from casadrone.cli import app
from casadrone.config.airframe import load_airframe
from casadrone.config.parts import (
    MotorEntry,
    PackEntry,
    PartsConfig,
    airframe_with_parts,
    battery_section,
    load_parts,
    motor_section,
    propeller_section,
)
from casadrone.parts import propeller_points, shipped_catalogue

DATA = Path(__file__).resolve().parents[2] / "casadrone" / "data" / "parts"
SHIPPED_DA4022 = DATA.parent / "propulsion" / "uiuc-da4022-5x3.75-3blade.csv"


def _rows(name: str) -> list[list[str]]:
    """A catalogue file read with csv.reader, positionally (the header row first)."""
    with open(DATA / name, encoding="utf-8", newline="") as fh:
        return [r for r in csv.reader(fh) if r and not r[0].startswith("#")]


# --------------------------------------------------------------------------------------------
# The files: a second parser, citations, sizes
# --------------------------------------------------------------------------------------------


def test_sizes_meet_the_issue():
    cat = shipped_catalogue()
    motors = cat.motors
    assert len(motors) >= 8
    # stator sizes from the names: 2205 to 2407 class (22xx-24xx)
    assert all(any(f"{s}" in m.name for s in ("2205", "2207", "2306", "2307", "2406"))
               for m in motors)
    assert {p.cells for p in cat.packs} == {4, 6}
    assert all(0.45 <= p.capacity_ah <= 1.8 for p in cat.packs)
    assert len(cat.packs) >= 6
    # every 4-6 inch propeller of volume 2 with a J sweep: 32 entries (counted in the mirror's
    # volume2_exp.csv by diameter 4-6 inch; volumes 1 and 3 have none that small)
    assert len(cat.propellers) == 32
    assert all(4 * 0.0254 <= p.diameter_m <= 6 * 0.0254 for p in cat.propellers)


def test_propeller_points_read_by_numpy_equal_the_loader():
    names = np.genfromtxt(DATA / "propellers.csv", delimiter=",", comments="#", skip_header=10,
                          usecols=0, dtype=str)
    values = np.genfromtxt(DATA / "propellers.csv", delimiter=",", comments="#", skip_header=10,
                           usecols=(1, 2, 3, 4))
    assert len(names) == len(values) == 2316  # the mirror's 4-6 inch rows (awk count)
    for name in ("uiuc-da4022-5x3.75-3blade", "uiuc-nr640-5x4.29-4blade",
                 "uiuc-vp-140x45mm-2blade"):
        np.testing.assert_array_equal(np.array(propeller_points(name)), values[names == name])
    assert set(names) == set(shipped_catalogue().names("propeller"))


def test_the_catalogue_holds_the_shipped_da4022_file_point_for_point():
    # the shipped dataset (a different file, read by np.loadtxt) is the same database entry
    shipped = np.loadtxt(SHIPPED_DA4022, delimiter=",", comments="#", skiprows=7)
    ours = np.array(propeller_points("uiuc-da4022-5x3.75-3blade"))
    np.testing.assert_array_equal(ours[np.lexsort(ours.T[::-1])],
                                  shipped[np.lexsort(shipped.T[::-1])])


@pytest.mark.parametrize("name", ["motors.csv", "packs.csv", "propeller-list.csv", "lipo-ocv.csv"])
def test_every_row_is_cited_and_every_figure_has_a_basis(name):
    head, *rows = _rows(name)
    assert rows
    source = head.index("source")
    bases = [i for i, h in enumerate(head) if h.endswith("_basis")]
    for row in rows:
        assert len(row) == len(head), row
        assert len(row[source]) > 20, row  # a citation, not a placeholder
        for i in bases:
            assert row[i] in ("datasheet", "measured", "assumed"), (row[0], head[i])
        if any(row[i] == "assumed" for i in bases):
            assert "assumed" in row[source], row[0]  # what was assumed is said


def test_motor_rows_read_by_csv_equal_the_records():
    head, *rows = _rows("motors.csv")
    cat = shipped_catalogue()
    assert [r[0] for r in rows] == cat.names("motor")
    for r in rows:
        m = cat.get(r[0], "motor")
        got = dict(zip(head, r, strict=True))
        assert m.kv_rpm_per_v == float(got["kv_rpm_per_v"])
        assert m.resistance_ohm == float(got["resistance_ohm"])
        assert m.no_load_current_a == float(got["no_load_current_a"])
        assert m.max_current_a == float(got["max_current_a"])
        assert m.mass_kg == float(got["mass_kg"])
        assert m.basis["resistance"] == got["resistance_basis"]


def test_pack_rows_read_by_csv_equal_the_records():
    head, *rows = _rows("packs.csv")
    for r in rows:
        got = dict(zip(head, r, strict=True))
        p = shipped_catalogue().get(got["name"], "pack")
        assert p.capacity_ah == pytest.approx(float(got["capacity_mah"]) / 1000, rel=1e-12)
        assert p.cells == int(got["cells"]) and p.c_rating == float(got["c_rating"])
        assert p.resistance_ohm == float(got["resistance_ohm"])


# --------------------------------------------------------------------------------------------
# Propeller fits
# --------------------------------------------------------------------------------------------


def _fit_points_by_hand(points: np.ndarray) -> np.ndarray:
    """Static rows at >= 5000 rpm (all static rows when none) and the highest-rpm sweep."""
    static = points[points[:, 0] == 0]
    fast = static[static[:, 1] >= 5000]
    sweep = points[(points[:, 0] > 0) & (points[:, 1] == points[points[:, 0] > 0, 1].max())]
    return np.vstack([fast if len(fast) else static, sweep])


@pytest.mark.parametrize("name", ["uiuc-da4022-5x3.75-3blade", "uiuc-gwsdd-5x4.3-2blade",
                                  "uiuc-nr640-5x4.29-4blade", "uiuc-apcff-4.2x4-2blade"])
def test_fit_equals_an_independent_least_squares_solve(name):
    part = shipped_catalogue().get(name)
    pts = _fit_points_by_hand(np.array(propeller_points(name)))
    A = np.vander(pts[:, 0], 3, increasing=True)
    for col, coeffs, rms in ((2, part.ct_coefficients, part.ct_rms),
                             (3, part.cp_coefficients, part.cp_rms)):
        c, *_ = np.linalg.lstsq(A, pts[:, col], rcond=None)
        np.testing.assert_allclose(coeffs, c, rtol=1e-7, atol=1e-10)
        residual = A @ c - pts[:, col]
        assert rms == pytest.approx(math.sqrt(np.mean(residual**2)), rel=1e-9)
    assert part.j_max_measured == pts[:, 0].max()


def test_raw_points_are_reproduced_within_the_stated_residual():
    for part in shipped_catalogue().propellers:
        pts = _fit_points_by_hand(np.array(propeller_points(part.name)))
        for col, c, rms in ((2, part.ct_coefficients, part.ct_rms),
                            (3, part.cp_coefficients, part.cp_rms)):
            err = np.abs(np.polynomial.polynomial.polyval(pts[:, 0], c) - pts[:, col])
            assert err.max() <= 4 * rms, part.name  # no point far outside the stated scatter
        assert part.ct_rms < 0.01 and part.cp_rms < 0.015  # C_T0 of these props: 0.05-0.25


def test_da4022_static_thrust_and_sweep_end_by_hand():
    part = shipped_catalogue().get("uiuc-da4022-5x3.75-3blade")
    # the file's static C_T at >= 5000 rpm (5198 ... 6947 rpm), typed in from its rows
    static = [0.210806, 0.2033, 0.209129, 0.20522, 0.209425, 0.2111, 0.211303, 0.212221]
    assert part.ct_coefficients[0] == pytest.approx(sum(static) / len(static), abs=0.002)
    # the 6034 rpm sweep ends at J = 0.854119 (issue 46: the measured sweep ends at J = 0.854),
    # past the shipped fit's 0.618
    assert part.j_max_measured == 0.854119
    assert part.sweep_rpm == 6034.0
    assert part.ct(part.j_max_measured) < 0.02  # thrust all but gone at the sweep's end


def test_reynolds_caveat_by_hand():
    part = shipped_catalogue().get("uiuc-da4022-5x3.75-3blade")
    # lowest sweep 4028 rpm; c/R at 0.75R = 0.2317 (volume2_geom.csv); R = 2.5 in; ISA air
    R = 2.5 * 0.0254
    V = 2 * math.pi * 4028 / 60 * 0.75 * R
    assert part.reynolds_075_min == pytest.approx(1.225 * V * 0.2317 * R / 1.789e-5, rel=1e-9)
    assert part.reynolds_075_min == pytest.approx(2.02e4, rel=0.01)
    assert "2.02e+04" in part.caveat and "30000 rpm" in part.caveat
    # a racing rotor at 30 000 rpm runs at 30000/4028 = 7.4 times that
    assert part.reynolds_at(30000) / part.reynolds_075_min == pytest.approx(30000 / 4028)
    no_geometry = shipped_catalogue().get("uiuc-da4052-5x1.58-2blade")
    assert no_geometry.reynolds_075_min is None and "no blade geometry" in no_geometry.caveat


# --------------------------------------------------------------------------------------------
# Physical ranges (bounds typed here with their source, not read from the code)
# --------------------------------------------------------------------------------------------


def test_motor_constants_are_physical():
    for m in shipped_catalogue().motors:
        kt = 60 / (2 * math.pi * m.kv_rpm_per_v)  # N·m/A
        # motor constant K_m = K_t/√R: the IQ2306 datasheet gives K_t 0.0043 N·m/A and 0.038 Ω,
        # K_m = 0.022 N·m/√W; 22xx-24xx stators lie within a factor 2 of it
        assert 0.011 <= kt / math.sqrt(m.resistance_ohm) <= 0.044, m.name
        # unloaded on a full 4S pack (16.8 V) a 5.1-inch tip stays below the speed of sound
        tip = math.pi * 5.1 * 0.0254 * m.kv_rpm_per_v * 16.8 / 60
        assert tip < 343, m.name
        # 30-80 mΩ, as every 22xx datasheet here; the no-load current a few % of the maximum
        assert 0.030 <= m.resistance_ohm <= 0.080, m.name
        assert 0.01 <= m.no_load_current_a / m.max_current_a <= 0.1, m.name
        assert 0.025 <= m.mass_kg <= 0.040, m.name


def test_shipped_parts_pass_the_user_file_checks():
    cat = shipped_catalogue()
    for m in cat.motors:
        MotorEntry(name=m.name, basis="datasheet", source=m.source,
                   **{k: getattr(m, k) for k in ("kv_rpm_per_v", "resistance_ohm",
                                                 "no_load_current_a", "no_load_voltage_v",
                                                 "max_current_a", "mass_kg")})
    for p in cat.packs:
        PackEntry(name=p.name, basis="datasheet", source=p.source, cells=p.cells,
                  capacity_ah=p.capacity_ah, resistance_ohm=p.resistance_ohm,
                  c_rating=p.c_rating, mass_kg=p.mass_kg, ocv_soc=p.ocv_soc, ocv=p.ocv)
        # 100-200 Wh/kg at 3.7 V nominal, as racing LiPos
        assert 100 <= p.cells * 3.7 * p.capacity_ah / p.mass_kg <= 200, p.name


def test_ocv_curve_matches_its_published_equation():
    pack = shipped_catalogue().get("dogcom-1300mah-6s")
    for soc in (0.0, 0.1, 0.5, 0.9, 1.0):  # Chen and Rincón-Mora 2006, eq. (1)
        v = -1.031 * math.exp(-35 * soc) + 3.685 + 0.2156 * soc - 0.1178 * soc**2 + 0.3201 * soc**3
        assert pack.open_circuit_voltage_v(soc) == pytest.approx(6 * v, abs=6e-4)
    assert all(b > a for a, b in zip(pack.ocv, pack.ocv[1:], strict=False))


# --------------------------------------------------------------------------------------------
# Parts into an airframe
# --------------------------------------------------------------------------------------------


def test_every_part_converts_into_its_section():
    cat = shipped_catalogue()
    for p in cat.propellers:
        section = propeller_section(p)
        assert section.max_advance_ratio == p.j_max_measured
    for m in cat.motors:
        assert motor_section(m).kv_rpm_per_v == m.kv_rpm_per_v
    pack = cat.get("cnhl-black-v2-1300mah-4s")
    assert battery_section(pack).open_circuit_voltage_v == pytest.approx(4 * 4.1029)
    assert battery_section(pack, soc=0.5).open_circuit_voltage_v == pytest.approx(4 * 3.8034)


def test_an_airframe_flies_catalogue_parts():
    cat = shipped_catalogue()
    cfg = airframe_with_parts(load_airframe("SY250-propeller"),
                              cat.get("uiuc-da4022-5x3.75-4blade"),
                              cat.get("tmotor-velox-v2207-v2-2550kv"),
                              cat.get("cnhl-black-v2-1300mah-4s"))
    assert cfg.propulsion.propeller.ct_coefficients == cat.get(
        "uiuc-da4022-5x3.75-4blade").ct_coefficients
    assert cfg.propulsion.propeller.rotor_inertia_kgm2 == 6.4e-6  # the airframe's own kept
    assert cfg.propulsion.motor.resistance_ohm == 0.043
    assert cfg.propulsion.battery.internal_resistance_ohm == 0.016
    with pytest.raises(ValueError, match="prop_diameter_mm"):  # a 4-inch prop on a 5-inch frame
        airframe_with_parts(load_airframe("SY250-propeller"), cat.get("uiuc-gwsdd-4x4-2blade"))


# --------------------------------------------------------------------------------------------
# The user's parts file and the command
# --------------------------------------------------------------------------------------------

GOOD_PACK = {"name": "my-pack", "basis": "measured", "source": "my charger's IR reading",
             "cells": 6, "capacity_ah": 1.3, "resistance_ohm": 0.03, "c_rating": 100,
             "mass_kg": 0.22}
GOOD_MOTOR = {"name": "my-motor", "basis": "measured", "source": "my stand", "kv_rpm_per_v": 1900,
              "resistance_ohm": 0.055, "no_load_current_a": 1.2, "no_load_voltage_v": 10,
              "max_current_a": 45, "mass_kg": 0.034}


def _write(tmp_path: Path, **sections) -> Path:
    path = tmp_path / "mine.yaml"
    path.write_text(yaml.safe_dump(sections), encoding="utf-8")
    return path


def test_shipped_example_propeller_says_its_caveat_is_unknown():
    part = load_parts(DATA.parent / "configs" / "parts" / "example-parts.yaml").get(
        "example-5x4.3-3blade")
    assert part.ct_coefficients == (0.20, -0.10, -0.18) and part.j_max_measured == 0.85
    assert "unknown" in part.caveat


def test_user_parts_join_the_catalogue(tmp_path, cli_runner):
    path = _write(tmp_path, motors=[GOOD_MOTOR], packs=[GOOD_PACK])
    cat = load_parts(path)
    assert cat.get("my-motor").basis["kv"] == "measured"
    assert cat.sizes()["pack"] == shipped_catalogue().sizes()["pack"] + 1
    out = cli_runner.invoke(app, ["parts", "--file", str(path), "--kind", "pack", "--json"])
    assert out.exit_code == 0, out.stderr
    listed = {p["name"]: p for p in json.loads(out.stdout)["parts"]}
    assert "my-pack" in listed and all(p["kind"] == "pack" for p in listed.values())
    assert listed["dogcom-1600mah-6s"]["max_current_a"] == pytest.approx(180 * 1.6)  # C × Ah
    assert listed["my-pack"]["full_voltage_v"] == pytest.approx(6 * 4.1029)


@pytest.mark.parametrize(("section", "change", "key"), [
    ("motors", {"mass_kg": -0.03}, "motors.0.mass_kg"),
    ("motors", {"kv_rpm_per_v": 250000}, "motors.0.kv_rpm_per_v"),
    ("motors", {"resistance_ohm": 0.0}, "motors.0.resistance_ohm"),
    ("motors", {"no_load_current_a": 50}, "motors.0.no_load_current_a"),
    ("motors", {"basis": "guessed"}, "motors.0.basis"),
    ("motors", {"name": "tmotor-velox-v2207-v2-1950kv"}, "motors.0.name"),
    ("packs", {"ocv_soc": [0, 0.5, 1], "ocv": [3.0, 3.9, 3.8]}, "packs.0.ocv"),
    ("packs", {"c_rating": 900}, "packs.0.c_rating"),  # 1170 A from 0.03 Ω: V/2R is 410 A
    ("packs", {"mass_kg": 0.05}, "packs.0.mass_kg"),  # 577 Wh/kg
    ("packs", {"ocv_curve": "nimh"}, "packs.0.ocv_curve"),
    ("packs", {"capacity_mah": 1300}, "packs.0.capacity_mah"),  # unknown key
])
def test_bad_user_parts_are_refused_in_one_line(tmp_path, cli_runner, section, change, key):
    entry = {**(GOOD_MOTOR if section == "motors" else GOOD_PACK), **change}
    path = _write(tmp_path, **{section: [entry]})
    out = cli_runner.invoke(app, ["parts", "--file", str(path)])
    assert out.exit_code == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"{path}: {key}:"), lines[0]
    assert out.stdout == ""


def test_an_airframe_given_as_a_parts_file_is_one_line(cli_runner):
    frame = DATA.parent / "configs" / "airframes" / "SY250.yaml"
    out = cli_runner.invoke(app, ["parts", "--file", str(frame)])
    assert out.exit_code == 2
    assert out.stderr.strip().splitlines() == [
        f"{frame}: this is an airframe, not a parts; give a parts here (a YAML file or a "
        "shipped name)"]


def test_a_name_given_twice_in_the_file_is_refused(tmp_path):
    path = _write(tmp_path, motors=[GOOD_MOTOR, GOOD_MOTOR])
    with pytest.raises(Exception, match=r"motors\.1\.name: 'my-motor' is given twice"):
        load_parts(path)


def test_command_lists_and_shows_one_part(cli_runner):
    out = cli_runner.invoke(app, ["parts", "--kind", "motor"])
    assert out.exit_code == 0
    assert "tmotor-velox-v2207-v2-1950kv" in out.stdout and "uiuc-" not in out.stdout
    one = cli_runner.invoke(app, ["parts", "emax-rs2205-2300kv"])
    assert "resistance assumed" in one.stdout and "source:" in one.stdout
    bad = cli_runner.invoke(app, ["parts", "tmotor-velox-2207"])
    assert bad.exit_code == 2 and len(bad.stderr.strip().splitlines()) == 1
    assert "did you mean" in bad.stderr
    assert cli_runner.invoke(app, ["parts", "--kind", "esc"]).exit_code == 2


def test_shipped_example_file_validates():
    assert isinstance(PartsConfig.model_validate(yaml.safe_load(
        (DATA.parent / "configs" / "parts" / "example-parts.yaml").read_text())), PartsConfig)


def test_plot_draws_one_propeller_and_the_overview(tmp_path, cli_runner):
    out = cli_runner.invoke(app, ["parts", "uiuc-da4022-5x3.75-3blade", "--plot", str(tmp_path)])
    assert out.exit_code == 0, out.stderr
    assert (tmp_path / "parts-uiuc-da4022-5x3.75-3blade.png").is_file()
    assert (tmp_path / "parts-propellers.svg").is_file()
