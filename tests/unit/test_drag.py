"""Body-drag forms (casadrone.drag): the paper's per-axis expression kept operation for operation,
RotorPy's isotropic form reproduced from its source, the form chosen per airframe through p in
the full model and the point mass, and the schema's refusal of a form a model cannot fly.

Oracles: RotorPy's parasitic drag D = −‖v‖ diag(c_D) v typed in from its source
(``rotorpy/vehicles/multirotor.py``; c_D,i = ½ ρ C_d·A_i) with hand-computed numbers; the paper's
−½ρ C_d·A_i |v_i| v_i written out in numpy; Newton's second law on the model's ẋ.
"""

from __future__ import annotations

import math
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import yaml

from casadrone.airframe import build_airframe
from casadrone.config import load_airframe
from casadrone.config.io import resolve_config
from casadrone.drag import SPEED_SMOOTHING_M_S, body_drag, drag_force
from casadrone.model import VEL, quadrotor_model

RHO, CDA = 1.225, (0.012, 0.012, 0.025)  # SY250's air and drag areas (SY250.yaml)


def _sym(q: dict | None):
    v, cda = ca.SX.sym("v", 3), ca.SX.sym("cda", 3)
    return ca.Function("d", [v, cda], [body_drag(v, RHO, cda, q)])


def test_per_axis_is_the_papers_expression_bit_for_bit():
    """Without a switch (the paper's model) and with the switch at 0 the force is the paper's
    −½ρ C_d·A_i |v_i| v_i to the last bit (numpy, the same operations in the same order)."""
    rng = np.random.default_rng(7)
    off = _sym(None)
    zero = _sym({"drag_isotropic": 0.0})
    for v in rng.uniform(-45, 45, (50, 3)):
        paper = -0.5 * RHO * np.array(CDA) * np.abs(v) * v
        assert np.array_equal(np.asarray(off(v, CDA)).ravel(), paper)
        assert np.array_equal(np.asarray(zero(v, CDA)).ravel(), paper)


def test_isotropic_reproduces_rotorpys_parasitic_drag():
    """RotorPy: D = −‖v‖ C_D v, C_D = diag(c_Dx, c_Dy, c_Dz) (N/(m/s)²). With c_D = (0.005,
    0.005, 0.01) at v = (3, −4, 12) m/s (‖v‖ = 13) by hand: D = (−0.195, 0.26, −1.56) N. The form
    here on C_d·A_i = 2 c_D,i / ρ gives it within the smoothing ε/‖v‖ (0.8 %), and exactly with
    the smoothed speed √(‖v‖² + ε²) − ε written out."""
    c_d = (0.005, 0.005, 0.01)
    cda = tuple(2 * c / RHO for c in c_d)
    v = (3.0, -4.0, 12.0)
    by_hand = (-0.195, 0.26, -1.56)
    ours = np.asarray(_sym({"drag_isotropic": 1.0})(v, cda)).ravel()
    np.testing.assert_allclose(ours, by_hand, rtol=SPEED_SMOOTHING_M_S / 13 * 1.01)
    eps = SPEED_SMOOTHING_M_S
    speed = math.sqrt(169 + eps**2) - eps
    np.testing.assert_allclose(ours, [-c * speed * x for c, x in zip(c_d, v, strict=True)],
                               rtol=1e-14)
    np.testing.assert_allclose(drag_force(v, RHO, cda, "isotropic"), ours, rtol=1e-14)
    np.testing.assert_allclose(drag_force(v, RHO, cda, "per-axis"),
                               [-c * abs(x) * x for c, x in zip(c_d, v, strict=True)], rtol=1e-14)


def test_the_forms_agree_on_the_axes_and_part_at_45_degrees():
    """Along a body axis the two forms give the same drag (within ε/V); at 45° between x and z
    at 45 m/s (SY250's areas) the per-axis drag is ½ρV²/2 (C_d·A_x, C_d·A_z) = (7.44, 15.50) N
    and the isotropic ½ρV²/√2 (C_d·A_x, C_d·A_z) = (10.52, 21.92) N (by hand): 7.1 N apart,
    22 m/s² on SY250's 0.320 kg."""
    for axis in range(3):
        v = [0.0, 0.0, 0.0]
        v[axis] = 30.0
        np.testing.assert_allclose(drag_force(v, RHO, CDA, "isotropic"),
                                   drag_force(v, RHO, CDA, "per-axis"),
                                   rtol=SPEED_SMOOTHING_M_S / 30, atol=0)
    V = 45.0
    v = (V / math.sqrt(2), 0.0, V / math.sqrt(2))
    per = drag_force(v, RHO, CDA, "per-axis")
    iso = drag_force(v, RHO, CDA, "isotropic")
    np.testing.assert_allclose(per, (-7.44, 0, -15.50), atol=0.01)
    # by hand without the smoothing, which takes ε/V = 0.2 % off
    np.testing.assert_allclose(iso, (-10.52, 0, -21.92), rtol=SPEED_SMOOTHING_M_S / V + 1e-3)
    gap = math.dist(per, iso)
    assert gap == pytest.approx(7.12, rel=0.01)
    assert gap / 0.320 == pytest.approx(22.2, abs=0.2)


def _xdot(frame, v_body):
    x = np.zeros(16)
    x[VEL] = v_body
    x[12:16] = 2000.0  # rad/s, rotors turning
    return np.asarray(quadrotor_model(frame.propulsion).f(x, np.full(4, 0.5), frame.p)).ravel()


def test_the_model_flies_the_airframes_form():
    """SY250-propeller level at v = (30, 0, 20) m/s, the same rotor speeds and commands with
    either form: the body accelerations differ by the difference of the two drags over the mass
    (Newton; the rotor forces, gravity and the rest are the same)."""
    v = (30.0, 0.0, 20.0)
    frames = {form: build_airframe(load_airframe("SY250-propeller", [f"drag_model={form}"]))
              for form in ("per-axis", "isotropic")}
    gap = _xdot(frames["isotropic"], v)[VEL] - _xdot(frames["per-axis"], v)[VEL]
    want = (np.array(drag_force(v, RHO, CDA, "isotropic"))
            - np.array(drag_force(v, RHO, CDA, "per-axis"))) / frames["per-axis"].mass
    assert np.linalg.norm(want) > 10  # m/s²: the forms are far apart here
    np.testing.assert_allclose(gap, want, rtol=1e-9, atol=1e-9)


def test_the_point_mass_flies_the_airframes_form():
    """The limit lap's point-mass relaxation reads the same switch: its acceleration at zero
    thrust and level attitude is the form's drag over the mass plus gravity."""
    from casadrone.limit.nlp import point_mass_ocp_model

    f = point_mass_ocp_model("propeller").f
    v = (25.0, -10.0, 15.0)
    for form in ("per-axis", "isotropic"):
        frame = build_airframe(load_airframe("SY250-propeller", [f"drag_model={form}"]))
        acc = np.asarray(f(np.r_[0, 0, 0, v], np.zeros(4), frame.p)).ravel()[3:]
        want = np.array(drag_force(v, RHO, CDA, form)) / frame.mass + (0, 0, -frame.gravity)
        np.testing.assert_allclose(acc, want, rtol=1e-12, atol=1e-12)


def test_the_racing_presets_fly_isotropic_drag_and_the_paper_frames_per_axis():
    for name in ("SY250-propeller", "HS210-propeller", "SY250-components-propeller"):
        assert load_airframe(name).drag_model == "isotropic"
    for name in ("SY250", "HS210", "SY250-components"):
        assert load_airframe(name).drag_model == "per-axis"
        assert build_airframe(load_airframe(name)).p.size == 31  # p as it was


def _frame(tmp_path: Path, base: str, **changes) -> Path:
    data = yaml.safe_load(resolve_config(base, "airframes").read_text("utf-8"))
    data.update(changes)
    path = tmp_path / "frame.yaml"
    path.write_text(yaml.safe_dump(data), "utf-8")
    return path


@pytest.mark.parametrize(("base", "value"), [("SY250", "isotropic"),
                                             ("SY250-propeller", "quadratic")])
def test_a_form_the_model_cannot_fly_is_refused_in_one_line(tmp_path, cli_runner, base, value):
    """The paper's model has no drag switch in p: isotropic is refused there; an unknown form
    everywhere. Exit 2, one line naming the file and drag_model."""
    from casadrone.cli import app

    path = _frame(tmp_path, base, drag_model=value)
    result = cli_runner.invoke(app, ["trim", str(path)])
    assert result.exit_code == 2, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{path}: drag_model: "), lines


def test_the_racing_preset_trims_fast_level_flight_from_its_own_drag():
    """The trim's analytic start balances the airframe's own drag form at the attitude it
    pitches to: SY250-propeller (isotropic) at 30 m/s level trims with IPOPT to Newton's root
    (nose-on drag alone started it 6° short, on a root with the rotors turning backwards)."""
    from casadrone.trim import trim

    frame = build_airframe(load_airframe("SY250-propeller"))
    ip, nt = trim(frame, "forward", 30.0, "ipopt"), trim(frame, "forward", 30.0, "newton")
    assert ip.success and nt.success, (ip.message, nt.message)
    np.testing.assert_allclose(ip.u0, nt.u0, rtol=1e-6)
    assert math.degrees(ip.x0[10]) == pytest.approx(70.4, abs=0.1)
