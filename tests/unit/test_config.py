"""Config schemas and loader: every shipped config validates; broken ones report every problem,
one ``FILE: key: message`` line each."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

from casadrone.airframe import TABLE1_BOUNDS
from casadrone.config import airframe as C
from casadrone.config import problem as P
from casadrone.config.airframe import AirframeConfig, load_airframe
from casadrone.config.controller import ControllerConfig, load_controller
from casadrone.config.io import CONFIG_DIR, ConfigError, Schema, apply_overrides, validate_data
from casadrone.optimise.checks import validate_file

ROOT = Path(__file__).resolve().parents[2]
BAD = ROOT / "tests" / "data" / "bad"
ALL_CONFIGS = sorted([*(ROOT / "configs").rglob("*.yaml"), *(ROOT / "problems").rglob("*.yaml")])

SY250 = {
    "name": "t",
    "lambda_a_mm": 125.0,
    "lambda_b_mm": 125.0,
    "alpha_deg": 90.0,
    "beta_deg": 90.0,
    "ixx_kgm2": 0.0022,
    "iyy_kgm2": 0.0017,
    "izz_kgm2": 0.0036,
    "mass_kg": 0.32,
}


def problems_of(data: dict, model=AirframeConfig, source: str = "f.yaml") -> list[str]:
    """The ConfigError lines of validating ``data``."""
    with pytest.raises(ConfigError) as info:
        validate_data(model, data, source, Path("."))
    return info.value.lines


def test_configs_exist():
    assert any("airframes" in p.parts for p in ALL_CONFIGS)
    assert any("problems" in p.parts for p in ALL_CONFIGS)
    assert (ROOT / "configs" / "controllers" / "default.yaml") in ALL_CONFIGS


@pytest.mark.parametrize("path", ALL_CONFIGS, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_shipped_config_validates(path):
    validate_file(path)


# ---------------------------------------------------------------------------------------------
# Broken files: each problem on its own line, FILE: dotted.key: message
# ---------------------------------------------------------------------------------------------

#: file → (dotted key, message fragment) lines that must appear (several per file allowed)
BAD_EXPECTED = {
    "misspelt_key.yaml": [("mas_kg", "unknown key (did you mean 'mass_kg'?)"),
                          ("mass_kg", "required key missing")],
    "misspelt_nested_key.yaml": [("thrust.gainn", "did you mean 'gain_n'")],
    "wrong_type.yaml": [("mass_kg", "expected a number, got the text 'heavy'")],
    "number_as_text.yaml": [("mass_kg", "expected a number, got the text '0.32'")],
    "bool_as_number.yaml": [("mass_kg", "expected a number, got the boolean true")],
    "infinite_inertia.yaml": [("ixx_kgm2", "finite"), ("drag_area_m2", "finite")],
    "huge_arm.yaml": [("lambda_a_mm", "beyond any physical value")],
    "controller_infinite_weight.yaml": [("r", "finite"), ("q_integral", "finite")],
    "track_repeated_waypoint.yaml": [("waypoints_m", "waypoint 2 is 0 m from the route point")],
    "track_infinite_waypoint.yaml": [("waypoints_m", "finite")],
    "problem_fixed_negative_mass.yaml": [("fixed.mass_kg", "greater than 0")],
    "problem_negative_seed.yaml": [("seed", "greater than or equal to 0")],
    "problem_negative_arm_bounds.yaml": [("variables.0.lower", "not a possible lambda_a_mm"),
                                         ("variables.0.upper", "not a possible lambda_a_mm")],
    "problem_text_variable.yaml": [("variables.0.name", "not a number the search can vary")],
    "problem_empty_box.yaml": [("variables", "cannot produce a valid airframe")],
    "problem_bad_evmoga_settings.yaml": [("algorithm.settings.n_ind_ga", "must be even"),
                                         ("algorithm.settings.n_div", "must be >= 1")],
    "problem_misspelt_setting.yaml": [("algorithm.settings.eliminate_duplicate",
                                       "did you mean 'eliminate_duplicates'")],
    "problem_population_contradiction.yaml": [("algorithm.settings.n_ind_p",
                                               "contradicts algorithm.population")],
    "problem_moead.yaml": [("algorithm.name", "handles no constraints")],
    "negative_mass.yaml": [("mass_kg", "greater than 0")],
    "angle_out_of_range.yaml": [("alpha_deg", "less than 180")],
    "overlapping_rotors.yaml": [("alpha_deg", "rotors FR and FL overlap")],
    "several_problems.yaml": [("mass_kg", "greater than 0"),
                              ("kapa_m", "did you mean 'kappa_m'"),
                              ("alpha_deg", "rotors FR and FL overlap")],
    "missing_reference.yaml": [("reference_airframe",
                                "referenced file not found: does-not-exist.yaml")],
    "controller_bad_weights.yaml": [("q.position.2", "greater than or equal to 0"),
                                    ("q.velocty", "did you mean 'velocity'"),
                                    ("r.1", "greater than 0")],
    "sample_time_too_long.yaml": [("sample_time_s", "less than or equal to 0.1")],
    "malformed.yaml": [("line 3", "malformed YAML")],
    "malformed_flow.yaml": [("line 4", "started on line 3")],
    "duplicate_key.yaml": [("line 3", "duplicate key 'lambda_a_mm' (first given on line 2)")],
    "bounds_inverted.yaml": [("variables.1.lower",
                              "lower bound 90.0 is not below upper bound 65.0")],
}


def test_every_bad_file_has_an_expectation():
    assert {p.name for p in BAD.glob("*.yaml")} == set(BAD_EXPECTED)


@pytest.mark.parametrize("name", sorted(BAD_EXPECTED))
def test_bad_file_reports_file_key_and_message(name):
    path = BAD / name
    with pytest.raises(ConfigError) as info:
        validate_file(path)
    lines = info.value.lines
    for key, fragment in BAD_EXPECTED[name]:
        prefix = f"{path}: {key}"
        assert any(ln.startswith(prefix) and fragment in ln for ln in lines), (key, lines)
    assert all(ln.startswith(f"{path}: ") and "\n" not in ln for ln in lines)


def test_several_problems_are_reported_at_once():
    # field errors, an unknown key and cross-field (geometry) errors in one report
    lines = problems_of({**SY250, "mass_kg": -1, "alpha_deg": 60, "lambda_a_mm": 110, "kapa": 1,
                         "rotor_spins": [1, 1, -1, -1], "drag_area_m2": [0.1, -0.1, 0.1]})
    keys = [ln.split(": ")[1] for ln in lines]
    assert keys == ["mass_kg", "drag_area_m2.1", "kapa", "rotor_spins", "alpha_deg"], lines


def test_nested_model_problems_get_dotted_keys():
    lines = problems_of({"q": {"position": [1, 1, -1]}, "thrust": 1}, ControllerConfig)
    assert "f.yaml: q.position.2: Input should be greater than or equal to 0 (got -1)" in lines
    assert any(ln.startswith("f.yaml: thrust: unknown key") for ln in lines)


def test_unknown_key_without_close_match_lists_known_keys():
    lines = problems_of({"q": {"zzz": 1}}, ControllerConfig)
    assert lines == ["f.yaml: q.zzz: unknown key; known keys: position, velocity, rates, "
                     "attitude, thrust"]


def test_plain_value_error_naming_a_field_gets_its_key():
    from pydantic import model_validator

    class Legs(Schema):
        waypoints: list[float]
        straight: list[bool]

        @model_validator(mode="after")
        def _same_length(self):
            if len(self.straight) != len(self.waypoints):
                raise ValueError("straight: needs one entry per waypoint")
            return self

    assert problems_of({"waypoints": [1, 2], "straight": [True]}, Legs) == [
        "f.yaml: straight: needs one entry per waypoint"
    ]


def test_cross_field_problems_of_list_items_are_reported_with_field_errors():
    from pydantic import Field

    class Bound(Schema):
        lower: float
        upper: float
        count: int = Field(1, ge=0)

        @classmethod
        def problems(cls, v):
            if "lower" in v and "upper" in v and v["lower"] >= v["upper"]:
                return [("lower", f"lower bound {v['lower']} is not below upper {v['upper']}")]
            return []

    class Bounds(Schema):
        bounds: list[Bound]

    lines = problems_of({"bounds": [{"lower": 0, "upper": 1},
                                    {"lower": 2, "upper": 1, "count": -1}]}, Bounds)
    assert lines == [
        "f.yaml: bounds.1.count: Input should be greater than or equal to 0 (got -1)",
        "f.yaml: bounds.1.lower: lower bound 2.0 is not below upper 1.0",
    ]


def test_wrong_tuple_length_is_one_line():
    assert problems_of({**SY250, "drag_area_m2": [0.1]}) == [
        "f.yaml: drag_area_m2: expected 3 values, got 1"
    ]


# ---------------------------------------------------------------------------------------------
# Geometry in physical sense
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("key", ["lambda_a_mm", "lambda_b_mm", "ixx_kgm2", "iyy_kgm2",
                                 "izz_kgm2", "mass_kg", "prop_diameter_mm"])
@pytest.mark.parametrize("value", [0.0, -1.0])
def test_non_positive_lengths_inertias_mass_rejected(key, value):
    lines = problems_of({**SY250, key: value})
    assert any(ln.startswith(f"f.yaml: {key}: Input should be greater than 0") for ln in lines)


@pytest.mark.parametrize("key", ["alpha_deg", "beta_deg"])
@pytest.mark.parametrize("value", [0.0, 180.0, -10.0, 200.0])
def test_angles_outside_open_interval_rejected(key, value):
    lines = problems_of({**SY250, key: value})
    assert lines and all(f": {key}: Input should be" in ln for ln in lines)


def test_rear_rotor_overlap_names_beta_and_minimum_angle():
    # HS200 rear arms: 100 mm; the props touch below beta = 2 asin(63.5 / 100) = 78.8 deg
    base = {**SY250, "lambda_a_mm": 100.0, "lambda_b_mm": 100.0}
    AirframeConfig(**{**base, "beta_deg": 80.0})
    (line,) = problems_of({**base, "beta_deg": 78.0})
    gap = 2 * 100 * math.sin(math.radians(39))
    assert line == (f"f.yaml: beta_deg: rotors RL and RR overlap: centres {gap:.1f} mm apart, "
                    "less than the prop diameter 127.0 mm (needs at least 78.8 deg)")


def test_rotors_exactly_touching_are_accepted():
    # front gap = 2 * la * sin(45 deg) equals the prop diameter
    la = 127.0 / (2 * math.sin(math.radians(45)))
    AirframeConfig(**{**SY250, "lambda_a_mm": la, "lambda_b_mm": la})


def test_side_overlap_reported_on_prop_diameter():
    lines = problems_of({**SY250, "alpha_deg": 170, "beta_deg": 170})
    assert any(ln.startswith("f.yaml: prop_diameter_mm: rotors FR and RR overlap") for ln in lines)


def test_inertia_tensor_must_be_positive_definite():
    (line,) = problems_of({**SY250, "ixy_kgm2": 0.003})
    assert line.startswith("f.yaml: ixy_kgm2: inertia tensor is not positive definite")
    AirframeConfig(**{**SY250, "ixy_kgm2": 0.0001})


def test_rotor_spins_must_pair_diagonals():
    (line,) = problems_of({**SY250, "rotor_spins": [1, 1, -1, -1]})
    assert line.startswith("f.yaml: rotor_spins: diagonal rotors must spin alike")
    assert any("rotor_spins.0: Input should be -1 or 1 (got 2)" in ln
               for ln in problems_of({**SY250, "rotor_spins": [2, 1, -1, 1]}))
    assert AirframeConfig(**{**SY250, "rotor_spins": [1, -1, 1, -1]}).rotor_spins == (1, -1, 1, -1)


def test_airframe_that_cannot_hover_is_rejected():
    (line,) = problems_of({**SY250, "mass_kg": 5.0})
    assert line.startswith("f.yaml: mass_kg: cannot hover")


# ---------------------------------------------------------------------------------------------
# Schemas: frozen, extra forbidden, defaults
# ---------------------------------------------------------------------------------------------


def _all_schemas(cls=Schema):
    for sub in cls.__subclasses__():
        yield sub
        yield from _all_schemas(sub)


def test_every_schema_is_frozen_and_forbids_extra_keys():
    from casadrone.config import controller, reference, track

    schemas = [s for s in _all_schemas() if s.__module__.startswith("casadrone.config.")]
    assert {AirframeConfig, ControllerConfig, controller.StateWeights, C.ThrustModelConfig,
            P.ProblemConfig, P.VariableConfig, P.AlgorithmConfig, track.TrackConfig,
            track.GateConfig, reference.Table4Reference} <= set(schemas)
    for s in schemas:
        assert s.model_config["frozen"] is True and s.model_config["extra"] == "forbid", s


def test_every_schema_lives_in_the_config_package():
    # read from the source: a pydantic model defined anywhere else in casadrone would be a YAML
    # schema outside casadrone/config (which imports no solver and feeds the YAML reference)
    import ast

    package = Path(C.__file__).resolve().parents[1]
    outside = []
    for path in package.rglob("*.py"):
        if "config" in path.relative_to(package).parts[:1]:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef) and any(
                    getattr(b, "id", getattr(b, "attr", "")) in ("Schema", "BaseModel")
                    for b in node.bases):
                outside.append(f"{path.relative_to(package)}:{node.lineno} {node.name}")
    assert outside == []


def test_configs_are_frozen():
    cfg = load_airframe("SY250")
    with pytest.raises(ValidationError):
        cfg.mass_kg = 1.0


def test_default_controller_file_equals_schema_defaults():
    assert load_controller() == ControllerConfig()
    assert load_controller("default") == load_controller(ROOT / "configs/controllers/default.yaml")
    assert load_controller().sample_time_s == 0.01


# ---------------------------------------------------------------------------------------------
# Loading: names, paths, overrides, references
# ---------------------------------------------------------------------------------------------


def test_airframe_by_name_or_path():
    assert load_airframe("SY250") == load_airframe(ROOT / "configs/airframes/SY250.yaml")
    assert load_airframe("SY250.yaml").name == "SY250"


def test_unknown_airframe_name_suggests_one():
    with pytest.raises(ConfigError) as info:
        load_airframe("SY25")
    (line,) = info.value.lines
    assert line.startswith("SY25: file not found") and "did you mean 'SY250'?" in line
    with pytest.raises(ConfigError, match="nowhere/x.yaml: file not found"):
        load_airframe("nowhere/x.yaml")


def test_an_empty_name_and_a_local_folder_are_named_for_what_they_are(tmp_path, monkeypatch):
    """``casadrone limit-lap ""`` (an unset shell variable) said ": file not found, and no
    shipped configs/airframes/.yaml", naming nothing; a folder of the given name in the working
    directory was "file not found" though it is right there."""
    with pytest.raises(ConfigError) as info:
        load_airframe("")
    (line,) = info.value.lines
    assert line.startswith("'': an empty name") and "SY250" in line
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine").mkdir()
    with pytest.raises(ConfigError) as info:
        load_airframe("mine")
    assert info.value.lines == ["mine: is a folder, not a file"]
    (tmp_path / "SY250").mkdir()  # a shipped name still finds the shipped file
    assert load_airframe("SY250").name == "SY250"


def test_overrides_are_validated_like_the_file():
    cfg = load_airframe("SY250", ["alpha_deg=75", "lambda_a_mm=140", "thrust.gain_n=10"])
    assert (cfg.alpha_deg, cfg.lambda_a_mm, cfg.thrust.gain_n) == (75.0, 140.0, 10.0)
    assert cfg.thrust.time_constant_s == 0.060538  # sibling nested key kept
    with pytest.raises(ConfigError) as info:
        load_airframe("SY250", ["alpha_deg=200", "thrust.gainn=3", "mass_kg=x"])
    src = str(CONFIG_DIR / "airframes/SY250.yaml")
    assert info.value.lines == [
        f"{src}: alpha_deg: Input should be less than 180 (got 200) [override alpha_deg=200]",
        f"{src}: mass_kg: expected a number, got the text 'x' [override mass_kg=x]",
        f"{src}: thrust.gainn: unknown key (did you mean 'gain_n'?) [override thrust.gainn=3]",
    ]


def test_override_syntax_errors():
    with pytest.raises(ConfigError) as info:
        apply_overrides({}, ["alpha_deg", "=3", "a..b=1"], "src")
    assert len(info.value.lines) == 3
    assert all(ln.startswith("src: override '") for ln in info.value.lines)
    assert apply_overrides({"a": {"b": 1}}, ["a.c=[1, 2]"], "s") == {"a": {"b": 1, "c": [1, 2]}}


def test_frozen_gain_reference_by_name_and_relative_path(tmp_path):
    (tmp_path / "frame.yaml").write_text(
        "\n".join(f"{k}: {v}" for k, v in SY250.items()) + "\n"
    )
    by_name = tmp_path / "by_name.yaml"
    by_name.write_text("gain_policy: frozen-command\nreference_airframe: SY250\n")
    found = validate_file(by_name).reference_airframe
    assert found.resolve() == (ROOT / "configs/airframes/SY250.yaml").resolve()
    rel = tmp_path / "rel.yaml"
    rel.write_text("gain_policy: frozen-command\nreference_airframe: frame.yaml\n")
    assert validate_file(rel).reference_airframe == tmp_path / "frame.yaml"


@pytest.mark.parametrize("policy", ["frozen-command", "frozen-wrench"])
def test_frozen_gain_without_reference(policy):
    assert problems_of({"gain_policy": policy}, ControllerConfig) == [
        f"f.yaml: reference_airframe: required when gain_policy is '{policy}'"
    ]


def test_old_frozen_policy_name_fails_with_the_new_names():
    (line,) = problems_of({"gain_policy": "frozen", "reference_airframe": "SY250"},
                          ControllerConfig)
    assert line.startswith("f.yaml: gain_policy: 'frozen' is now called 'frozen-command'")
    assert "'frozen-wrench'" in line


def test_referenced_file_that_is_invalid_is_reported(tmp_path):
    (tmp_path / "frame.yaml").write_text("name: x\nlambda_a_mm: -1\n")
    ctrl = tmp_path / "ctrl.yaml"
    ctrl.write_text("gain_policy: frozen-command\nreference_airframe: frame.yaml\n")
    with pytest.raises(ConfigError) as info:
        validate_file(ctrl)
    lines = info.value.lines
    assert f"{ctrl}: reference_airframe: referenced file is invalid" in lines
    assert any(ln.startswith(f"{tmp_path / 'frame.yaml'}: lambda_a_mm: Input should be greater")
               for ln in lines)


def test_unknown_reference_name_suggests_one(tmp_path):
    ctrl = tmp_path / "ctrl.yaml"
    ctrl.write_text("gain_policy: frozen-command\nreference_airframe: SY25\n")
    with pytest.raises(ConfigError) as info:
        validate_file(ctrl)
    (line,) = info.value.lines
    assert line.startswith(f"{ctrl}: reference_airframe: referenced file not found: SY25")
    assert "did you mean 'SY250'?" in line


def test_file_of_unknown_kind(tmp_path):
    f = tmp_path / "x.yaml"
    f.write_text("colour: blue\n")
    with pytest.raises(ConfigError, match="cannot tell what kind of config"):
        validate_file(f)


@pytest.mark.parametrize("text, message", [
    ("- 1\n- 2\n", "top level must be a mapping"),
    ("", "required key missing"),
])
def test_top_level_shape(tmp_path, text, message):
    f = tmp_path / "airframes" / "x.yaml"
    f.parent.mkdir()
    f.write_text(text)
    with pytest.raises(ConfigError, match=message):
        validate_file(f)


def test_missing_file():
    with pytest.raises(ConfigError, match="no/such.yaml: file not found"):
        validate_file("no/such.yaml")


# ---------------------------------------------------------------------------------------------
# Possible rigid bodies only: positive definite, triangle inequalities on the principal moments
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("moments, key, inequality", [
    ((0.0022, 0.0017, 0.0045), "izz_kgm2", "Ixx + Iyy ≥ Izz"),
    ((0.0060, 0.0017, 0.0036), "ixx_kgm2", "Iyy + Izz ≥ Ixx"),
    ((0.0012, 0.0060, 0.0036), "iyy_kgm2", "Ixx + Izz ≥ Iyy"),
])
def test_triangle_inequality_violations_name_the_inequality(moments, key, inequality):
    data = {**SY250, **dict(zip(("ixx_kgm2", "iyy_kgm2", "izz_kgm2"), moments, strict=True))}
    (line,) = problems_of(data)
    assert line.startswith(f"f.yaml: {key}: {inequality} violated"), line


def test_flat_body_meets_the_triangle_inequality_with_equality():
    AirframeConfig.model_validate({**SY250, "izz_kgm2": 0.0022 + 0.0017})


def test_full_tensor_checked_on_its_principal_moments():
    """diag(1, 1, 3)·1e-3 (impossible) turned 10° about x: every diagonal entry is below the
    sum of the other two in the naive check, yet the principal moments are the same."""
    c, s = math.cos(math.radians(10)), math.sin(math.radians(10))
    R = [[1, 0, 0], [0, c, -s], [0, s, c]]
    D = [1e-3, 1e-3, 3e-3]
    J = [[sum(R[i][k] * D[k] * R[j][k] for k in range(3)) for j in range(3)] for i in range(3)]
    data = {**SY250, "ixx_kgm2": J[0][0], "iyy_kgm2": J[1][1], "izz_kgm2": J[2][2],
            "iyz_kgm2": J[1][2]}
    (line,) = problems_of(data)
    assert line.startswith("f.yaml: izz_kgm2: principal moments violate the triangle inequality")


def test_inertia_problems_agree_with_an_eigenvalue_oracle():
    """Random symmetric positive-definite tensors: refused exactly when numpy's principal moments
    break a triangle inequality; tensors of random point clouds (real bodies) never are."""
    rng = np.random.default_rng(7)
    refused = 0
    for _ in range(300):
        L = rng.normal(size=(3, 3))
        J = L @ L.T + 0.05 * np.eye(3)
        m = np.linalg.eigvalsh(J)
        impossible = m[2] > m[0] + m[1] + 1e-12
        refused += impossible
        assert bool(C.inertia_problems(J.tolist())) == impossible
        pts, w = rng.normal(size=(6, 3)), rng.uniform(0.1, 1, 6)
        pts -= (w @ pts) / w.sum()
        body = sum(wi * (p @ p * np.eye(3) - np.outer(p, p)) for wi, p in zip(w, pts, strict=True))
        assert C.inertia_problems(body.tolist()) == []
    assert 0 < refused < 300  # both outcomes were exercised


def test_table1_box_is_partly_impossible():
    """Izz ≤ Ixx + Iyy over the uniform Table 1 inertia box: by exact integration (the box
    volume below the plane), and the schema agrees on a grid."""
    from casadrone.airframe import TABLE1_BOUNDS as B

    (x0, x1), (y0, y1), (z0, z1) = B["ixx_kgm2"], B["iyy_kgm2"], B["izz_kgm2"]
    # P(Z ≤ X + Y): integrate the clipped length of [z0, min(z1, x + y)] over the x-y rectangle
    n = 400
    xs = x0 + (x1 - x0) * (np.arange(n) + 0.5) / n
    ys = y0 + (y1 - y0) * (np.arange(n) + 0.5) / n
    s = xs[:, None] + ys[None, :]
    p_feasible = float(np.mean(np.clip(s - z0, 0, z1 - z0)) / (z1 - z0))
    assert 0.68 < p_feasible < 0.74  # the measurement: 29 % impossible
    grid = [(x, y, z) for x in xs[::80] for y in ys[::80] for z in np.linspace(z0, z1, 5)]
    for x, y, z in grid:
        ok = not C.inertia_problems([[x, 0, 0], [0, y, 0], [0, 0, z]])
        assert ok == (z <= x + y)


def test_components_problem_refuses_mass_and_inertia_variables(tmp_path):
    problem = tmp_path / "p.yaml"
    problem.write_text("name: p\nairframe: SY250-components\nobjectives: [{index: J3}]\n")
    (line,) = problems_of_file(problem)  # the default variables: named as the default (the
    assert line.split(": ")[1] == "variables"  # file has no variables.4 to point at)
    assert "default (paper Table 1)" in line and "ixx_kgm2, iyy_kgm2, izz_kgm2" in line
    assert "computes from the parts" in line
    problem.write_text(problem.read_text() + "variables:\n" + "".join(
        f"  - {{name: {k}, lower: {lo}, upper: {hi}}}\n"
        for k, (lo, hi) in list(TABLE1_BOUNDS.items())[3:5]))
    lines = problems_of_file(problem)  # written in the file: named where they are
    assert [ln.split(": ")[1] for ln in lines] == ["variables.1.name"]
    assert "computed from the parts" in lines[0]
    problem.write_text("name: p\nairframe: SY250-components\nobjectives: [{index: J3}]\n")
    problem.write_text(problem.read_text() + "variables:\n" + "".join(
        f"  - {{name: {k}, lower: {lo}, upper: {hi}}}\n"
        for k, (lo, hi) in list(TABLE1_BOUNDS.items())[:4]))
    validate_file(problem)


def test_components_mode_refuses_given_mass_and_needs_its_parts():
    base = {k: v for k, v in SY250.items() if k not in C.MASS_KEYS}
    lines = problems_of({**base, "mass_model": "components", "mass_kg": 0.3})
    assert "f.yaml: components: required when mass_model is 'components'" in lines
    assert any(ln.startswith("f.yaml: mass_kg: computed from the components") for ln in lines)
    lines = problems_of(base)
    assert [ln.split(": ")[1] for ln in lines] == ["mass_kg", "ixx_kgm2", "iyy_kgm2", "izz_kgm2"]


def problems_of_file(path) -> list[str]:
    with pytest.raises(ConfigError) as info:
        validate_file(path)
    return info.value.lines


@pytest.mark.parametrize("key", ["izz_kgm2", "ixz_kgm2"])
def test_non_finite_inertia_is_named(key):
    (line,) = problems_of({**SY250, key: float("inf")})  # refused by the field's strict check
    assert line == f"f.yaml: {key}: expected a finite number, got inf"
