"""casadrone export: every format for the reference airframes, checked against independent oracles
(Betaflight's own QUADX table, a mix derived by hand, PX4's FRD frame, a third-party URDF parser,
the DXF read back by ezdxf)."""

from __future__ import annotations

import io
import math
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from casadrone import __version__
from casadrone.export import FORMATS, export, write_export
from casadrone.export.mixers import BETAFLIGHT_ORDER, motor_mix, to_frd
from casadrone.export.plate import PlateOptions, plate
from casadrone.export.source import source_of

FRAMES = ("SY250", "HS210", "NSY200")

#: Betaflight's built-in QUADX mix, src/main/flight/mixer_init.c (throttle, roll, pitch, yaw):
#: motor 1 REAR_R, 2 FRONT_R, 3 REAR_L, 4 FRONT_L.
QUADX = [[1.0, -1.0, 1.0, -1.0], [1.0, -1.0, -1.0, 1.0], [1.0, 1.0, 1.0, 1.0],
         [1.0, 1.0, -1.0, -1.0]]


def mmix_rows(text: str) -> np.ndarray:
    rows = [line.split() for line in text.splitlines() if line.startswith("mmix ")
            and line != "mmix reset"]
    assert [int(r[1]) for r in rows] == list(range(len(rows)))
    return np.array([[float(v) for v in r[2:]] for r in rows])


def qgc_rows(text: str) -> list[list[str]]:
    """The rows QGroundControl reads from a parameter file, by its own rules
    (``ParameterManager::readParametersFromStream``, src/FactSystem/ParameterManager.cc): every
    line not starting with ``#`` split at tabs; only lines of exactly 5 fields are read (any other
    is skipped without a word, so none may exist here)."""
    rows = [line.split("\t") for line in text.splitlines() if not line.startswith("#")]
    assert all(len(r) == 5 for r in rows), "QGroundControl would skip a line silently"
    return rows


#: PX4's types for the parameters written (control_allocator module.yaml: the two enums are
#: INT32, MAV_PARAM_TYPE 6; the geometry FLOAT, REAL32 = 9). QGroundControl skips a type mismatch.
PX4_TYPES = {"CA_AIRFRAME": 6, "CA_ROTOR_COUNT": 6}


def px4_params(text: str) -> dict[str, float]:
    out = {}
    for sysid, compid, name, value, kind in qgc_rows(text):
        assert (int(sysid), int(compid)) == (1, 1)  # PX4's autopilot: system 1, component 1
        assert int(kind) == PX4_TYPES.get(name, 9), name
        assert len(name) <= 16  # MAVLink's param_id
        out[name] = int(value) if int(kind) == 6 else float(value)
    return out


def test_px4_file_is_qgroundcontrols_and_says_how_to_apply_it():
    text = export(source_of("SY250"), "px4")
    params = px4_params(text)
    assert len(params) == 2 + 4 * 4
    assert "# Vehicle-Id Component-Id Name Value Type" in text.splitlines()
    assert "Load from file" in text and "reboot" in text
    shell = {m[1]: float(m[2]) for m in re.finditer(r"^param set (\S+) (\S+)$",
                                                     export(source_of("SY250"), "px4-shell"),
                                                     re.M)}
    assert shell == params  # the same parameters for the NSH console


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("fmt", list(FORMATS))
def test_every_format_carries_its_header(frame, fmt):
    text = export(source_of(frame), fmt)
    head = text[:4000] if fmt != "dxf" else text
    assert f"casadrone {__version__}" in head
    assert f"airframe {frame}" in head and "candidate: -" in head


def test_sy250_betaflight_mix_is_quadx():
    text = export(source_of("SY250"), "betaflight")
    np.testing.assert_array_equal(mmix_rows(text), QUADX)
    lines = text.splitlines()
    assert lines.index("mixer CUSTOM") < lines.index("mmix reset") < lines.index("mmix 0 "
                                                                                 "1.000000 "
                                                                                 "-1.000000 "
                                                                                 "1.000000 "
                                                                                 "-1.000000")
    assert "set yaw_motors_reversed = OFF" in lines
    # motor order and spin stated: motor 1 rear-right CW, 2 front-right CCW (Betaflight props in)
    assert re.search(r"motor 1 \(mmix 0\) = RR rear-right rotor, turning CW", text)
    assert re.search(r"motor 2 \(mmix 1\) = FR front-right rotor, turning CCW", text)


def test_mirrored_spins_are_props_out_with_the_same_table():
    text = export(source_of("SY250", overrides=["rotor_spins=[1, -1, 1, -1]"]), "betaflight")
    np.testing.assert_array_equal(mmix_rows(text), QUADX)
    assert "set yaw_motors_reversed = ON" in text.splitlines()
    assert re.search(r"motor 1 \(mmix 0\) = RR rear-right rotor, turning CCW", text)


@pytest.mark.parametrize(("la", "lb", "alpha", "beta"), [(140.0, 110.0, 90.0, 90.0),
                                                         (140.0, 110.0, 76.0, 88.0)])
def test_asymmetric_mix_derived_by_hand(la, lb, alpha, beta):
    # Rotors FR (a cA, -a sA), FL (a cA, a sA), RL (-b cB, b sB), RR (-b cB, -b sB) with
    # cA = cos(α/2) …; spins FR, RL counter-clockwise. Solving B T = e_k by hand:
    # roll  T = p(-1, 1, 1, -1), pitch T = q(-1, -1, 1, 1): yaw-free only with equal magnitudes,
    #       p = 1/(2(a sA + b sB)), q = 1/(2(a cA + b cB));
    # thrust: front pair f, rear pair r with f a cA = r b cB (no pitch moment);
    # yaw: front ±b sB, rear ±a sA (no roll moment), + on the CCW rotors.
    src = source_of("SY250", overrides=[f"lambda_a_mm={la}", f"lambda_b_mm={lb}",
                                        f"alpha_deg={alpha}", f"beta_deg={beta}"])
    a, b = la, lb
    sa, ca = math.sin(math.radians(alpha / 2)), math.cos(math.radians(alpha / 2))
    sb, cb = math.sin(math.radians(beta / 2)), math.cos(math.radians(beta / 2))
    p, q = 1 / (2 * (a * sa + b * sb)), 1 / (2 * (a * ca + b * cb))
    scale = max(p, q)
    f, r = b * cb, a * ca
    by_hand = {  # casadrone rotor order FR, FL, RL, RR
        "throttle": np.array([f, f, r, r]) / max(f, r),
        "roll": np.array([-p, p, p, -p]) / scale,
        "pitch": np.array([-q, -q, q, q]) / scale,
        "yaw": np.array([b * sb, -b * sb, a * sa, -a * sa]) / max(a * sa, b * sb),
    }
    mix = motor_mix(src.airframe)
    for axis, want in by_hand.items():
        np.testing.assert_allclose(getattr(mix, axis), want, atol=1e-9, err_msg=axis)
    # and the CLI lines carry them in Betaflight's motor order
    rows = mmix_rows(export(src, "betaflight"))
    for col, axis in enumerate(("throttle", "roll", "pitch", "yaw")):
        np.testing.assert_allclose(rows[:, col], by_hand[axis][list(BETAFLIGHT_ORDER)], atol=2e-6)


@pytest.mark.parametrize("frame", FRAMES)
def test_each_mix_column_is_a_pure_thrust_or_moment(frame):
    # property: B · column_k has only component k (no cross-coupling), for any geometry
    a = source_of(frame).airframe
    mix = motor_mix(a)
    B = a.allocation_matrix
    for k, col in enumerate((mix.throttle, mix.roll, mix.pitch, -mix.yaw)):
        wrench = B @ col
        off = np.delete(wrench, k)
        np.testing.assert_allclose(off, 0.0, atol=1e-12 * abs(wrench[k]) + 1e-15)
        assert wrench[k] > 0


def test_px4_positions_in_frd():
    src = source_of("HS210")
    params = px4_params(export(src, "px4"))
    assert params["CA_AIRFRAME"] == 0 and params["CA_ROTOR_COUNT"] == 4
    r = src.airframe.rotor_positions  # FR, FL, RL, RR in x forward, y left, z up
    # PX4 quad-x numbering: 0 front-right, 1 rear-left, 2 front-left, 3 rear-right
    for n, label in enumerate(("FR", "RL", "FL", "RR")):
        i = ("FR", "FL", "RL", "RR").index(label)
        px, py, pz = (params[f"CA_ROTOR{n}_P{c}"] for c in "XYZ")
        assert px == pytest.approx(r[i, 0], abs=1e-5)
        assert py == pytest.approx(-r[i, 1], abs=1e-5)  # FRD: y to the right
        assert pz == pytest.approx(-r[i, 2], abs=1e-5)  # FRD: z down
        # front rotors ahead (x > 0), right rotors have y > 0 in FRD
        assert (px > 0) == label.startswith("F") and (py > 0) == label.endswith("R")
        # PX4: KM > 0 for a counter-clockwise rotor; casadrone spin -1 = CCW seen from above
        ccw = src.airframe.rotor_spins[i] < 0
        assert params[f"CA_ROTOR{n}_KM"] == pytest.approx(
            (1 if ccw else -1) * src.airframe.kappa, abs=1e-6)


def test_frd_conversion_is_a_proper_rotation():
    R = np.diag(to_frd(np.eye(3)).diagonal())
    np.testing.assert_allclose(to_frd(np.eye(3)), R)
    assert np.linalg.det(R) == pytest.approx(1.0)  # 180° about x, not a reflection
    np.testing.assert_allclose(to_frd([0.1, 0.2, 0.3]), [0.1, -0.2, -0.3])


@pytest.mark.parametrize("frame", [*FRAMES, "SY250-components"])
def test_urdf_parsed_by_yourdfpy_round_trips(frame, tmp_path):
    yourdfpy = pytest.importorskip("yourdfpy")
    src = source_of(frame)
    path = write_export(src, "urdf", tmp_path / f"{frame}.urdf")
    robot = yourdfpy.URDF.load(str(path), load_meshes=False, build_scene_graph=False)
    model = robot.robot
    links = {link.name: link for link in model.links}
    total = sum(link.inertial.mass for link in model.links if link.inertial is not None)
    assert total == pytest.approx(src.airframe.mass, rel=1e-9)
    assert links["base_link"].inertial.mass < total  # the props are links of their own
    # (the links' composite inertia: test_export_consumers.test_urdf_links_sum_to_the_airframe)
    joints = {j.child: j for j in model.joints}
    for i, label in enumerate(("FR", "FL", "RL", "RR")):
        j = joints[f"rotor_{label}"]
        assert j.type == "continuous" and j.parent == "base_link"
        np.testing.assert_allclose(j.origin[:3, 3], src.airframe.rotor_positions[i], atol=1e-9)
        # spin axis: +z (up) for a counter-clockwise rotor
        np.testing.assert_allclose(j.axis, [0, 0, -src.airframe.rotor_spins[i]])


def test_urdf_is_well_formed_xml_with_header_comment():
    text = export(source_of("SY250"), "urdf")
    root = ET.fromstring(text.encode())
    assert root.tag == "robot" and root.get("name") == "SY250"


@pytest.mark.parametrize("frame", [*FRAMES, "SY250-components"])
def test_dxf_read_back_by_ezdxf(frame):
    ezdxf = pytest.importorskip("ezdxf")
    src = source_of(frame)
    doc = ezdxf.read(io.StringIO(export(src, "dxf")))
    assert doc.units == 4  # millimetres
    msp = doc.modelspace()
    points = [p.dxf.location for p in msp.query("POINT[layer=='MOTOR_CENTRES']")]
    # drawing origin at the hub: rotor positions are from the centre of mass, the CoM from the hub
    r = src.airframe.rotor_positions + src.airframe.com
    expected = np.stack([-1000 * r[:, 1], 1000 * r[:, 0]], axis=1)  # X right, Y nose (mm)
    got = np.array([[p.x, p.y] for p in points])
    np.testing.assert_allclose(got, expected, atol=0.01)
    if frame == "SY250":  # hand values: λ = 125 mm at 45°: (±88.388, ±88.388) mm
        np.testing.assert_allclose(np.abs(got), 125 / math.sqrt(2), atol=0.01)
    (com,) = msp.query("POINT[layer=='COM']")
    c = src.airframe.com
    np.testing.assert_allclose([com.dxf.location.x, com.dxf.location.y],
                               [-1000 * c[1], 1000 * c[0]], atol=0.01)
    # centre holes on the same centres; 4 mounting holes per motor on the 16 × 19 mm pattern
    holes = [(c.dxf.center, c.dxf.radius) for c in msp.query("CIRCLE[layer=='HOLES']")]
    for m in expected:
        near = sorted(math.hypot(c.x - m[0], c.y - m[1]) for c, _ in holes)[:5]
        np.testing.assert_allclose(near, [0.0, 8.0, 8.0, 9.5, 9.5], atol=0.01)
    # prop discs as construction circles of the prop radius
    props = msp.query("CIRCLE[layer=='PROPS']")
    assert len(props) == 4 and all(
        c.dxf.radius == pytest.approx(src.config.prop_diameter_mm / 2) for c in props)
    assert doc.layers.get("PROPS").dxf.linetype.upper() == "DASHED"
    # one closed outline; every motor centre inside it, the plate centre too
    (outline,) = msp.query("LWPOLYLINE[layer=='OUTLINE']")
    assert outline.closed
    from ezdxf import path
    from ezdxf.math import Vec2, is_point_in_polygon_2d
    poly = [Vec2(v) for v in path.make_path(outline).flattening(0.01)]  # arcs (bulges) included
    for m in [*expected, (0.0, 0.0)]:
        assert is_point_in_polygon_2d(Vec2(m), poly) == 1
    assert len(msp.query("DIMENSION")) == 3
    header = dict(doc.header.custom_vars)
    assert any(f"casadrone {__version__}" in v for v in header.values())


def test_plate_outline_is_continuous_and_arm_width_exact():
    src = source_of("NSY200")
    p = plate(src, PlateOptions(arm_width_mm=12.0, pattern="16x16"))

    def ends(piece):
        if piece[0] == "line":
            return np.array(piece[1]), np.array(piece[2])
        a = piece[1]
        at = [np.array(a.centre) + a.radius * np.array([math.cos(t), math.sin(t)])
              for t in (a.start, a.end)]
        return at[0], at[1]

    pieces = [ends(piece) for piece in p.outline]
    for (_, end), (start, _) in zip(pieces, pieces[1:] + pieces[:1], strict=True):
        np.testing.assert_allclose(end, start, atol=1e-9)
    for k in range(4):  # the two edges of arm k are 12 mm apart
        (r0, r1), (_, l1) = pieces[4 * k], pieces[4 * k + 2]
        u = (r1 - r0) / np.linalg.norm(r1 - r0)
        gap = l1 - r0
        assert abs(u[0] * gap[1] - u[1] * gap[0]) == pytest.approx(12.0, abs=1e-9)


def test_svg_is_one_to_one_millimetres():
    text = export(source_of("SY250"), "svg")
    root = ET.fromstring(text.encode())
    w, h = root.get("width"), root.get("height")
    assert w.endswith("mm") and h.endswith("mm")
    vb = [float(v) for v in root.get("viewBox").split()]
    assert float(w[:-2]) == pytest.approx(vb[2]) and float(h[:-2]) == pytest.approx(vb[3])
    ns = {"s": "http://www.w3.org/2000/svg"}
    centres = root.findall("s:circle[@class='motor-centre']", ns)
    got = sorted((float(c.get("cx")), -float(c.get("cy"))) for c in centres)
    r = source_of("SY250").airframe.rotor_positions
    want = sorted(zip(-1000 * r[:, 1], 1000 * r[:, 0], strict=True))
    np.testing.assert_allclose(got, want, atol=1e-3)


def test_plate_refuses_impossible_geometry():
    with pytest.raises(ValueError, match="narrower"):
        plate(source_of("SY250"), PlateOptions(arm_width_mm=40.0))
    with pytest.raises(ValueError, match="pattern"):
        plate(source_of("SY250"), PlateOptions(pattern="30x30"))


def test_unknown_format_and_wrong_candidate():
    with pytest.raises(ValueError, match="one of"):
        export(source_of("SY250"), "stl")
    with pytest.raises(ValueError, match="not a run directory"):
        source_of("SY250", candidate="A")


def svg_arc_centres(d: str) -> list[tuple[float, float]]:
    """Centres of the circular arcs of an SVG path, by the SVG spec's endpoint-to-centre
    conversion (SVG 1.1 appendix F.6.5, rx = ry, no rotation)."""
    tokens = re.findall(r"[MLAZ]|-?\d+(?:\.\d+)?", d)
    centres, here, i = [], None, 0
    while i < len(tokens):
        t = tokens[i]
        if t in "ML":
            here = (float(tokens[i + 1]), float(tokens[i + 2]))
            i += 3
        elif t == "A":
            r, large, sweep = float(tokens[i + 1]), int(tokens[i + 4]), int(tokens[i + 5])
            end = (float(tokens[i + 6]), float(tokens[i + 7]))
            x1p, y1p = (here[0] - end[0]) / 2, (here[1] - end[1]) / 2
            coef = math.sqrt(max(0.0, (r ** 4 - r * r * (x1p ** 2 + y1p ** 2))
                                 / (r * r * (x1p ** 2 + y1p ** 2))))
            sign = -1.0 if large == sweep else 1.0
            centres.append((sign * coef * y1p + (here[0] + end[0]) / 2,
                            -sign * coef * x1p + (here[1] + end[1]) / 2))
            here = end
            i += 8
        else:
            i += 1
    return centres


@pytest.mark.parametrize("frame", FRAMES)
def test_svg_outline_arcs_turn_about_the_motors_and_the_hub(frame):
    src = source_of(frame)
    root = ET.fromstring(export(src, "svg").encode())
    (path,) = root.findall("{http://www.w3.org/2000/svg}path")
    d = re.sub(r"([MLAZ])", r" \1 ", path.get("d")).replace(",", " ")
    centres = np.array(svg_arc_centres(d))
    r = src.airframe.rotor_positions + src.airframe.com
    motors_svg = np.stack([-1000 * r[:, 1], -1000 * r[:, 0]], axis=1)  # page: X right, Y down
    pads, hubs = centres[0::2], centres[1::2]
    for m in motors_svg:  # each motor centre is the centre of exactly one pad arc
        assert np.sum(np.linalg.norm(pads - m, axis=1) < 1e-3) == 1
    np.testing.assert_allclose(hubs, 0.0, atol=1e-3)


def test_px4_sy250_has_the_sign_pattern_of_px4s_own_quad_x():
    # PX4's x500 airframe (ROMFS init.d-posix/airframes, gz_x500): rotor 0 (+0.13, +0.22) KM +0.05,
    # 1 (-0.13, -0.20) +0.05, 2 (+0.13, -0.22) -0.05, 3 (-0.13, +0.20) -0.05 (FRD, KM > 0 = CCW)
    x500 = [(1, 1, 1), (-1, -1, 1), (1, -1, -1), (-1, 1, -1)]
    params = px4_params(export(source_of("SY250"), "px4"))
    got = [tuple(int(np.sign(params[f"CA_ROTOR{n}_{k}"])) for k in ("PX", "PY", "KM"))
           for n in range(4)]
    assert got == x500
