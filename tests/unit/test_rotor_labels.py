"""Every output names the rotor at each position alike (issue 44, item 5): the report's airframe
figure, ``simulate``'s rotor table and each export. The oracle is geometry, not the code's own
table: each rotor's position is read from the coordinates the output itself gives (x > 0 front,
y > 0 left; PX4's FRD y > 0 right; drawings X = right, Y = nose) and must match its label, and the
firmware numbers are typed in from the firmwares' sources."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import pytest

from casadrone import plots
from casadrone.config.airframe import (
    MOTOR_NUMBERING,
    ROTOR_LABELS,
    position_of,
    rotor_label,
)
from casadrone.export import export
from casadrone.export.source import source_of

#: Betaflight QUADX (src/main/flight/mixer_init.c): motor 1 REAR_R, 2 FRONT_R, 3 REAR_L, 4 FRONT_L.
BETAFLIGHT = {1: "RR", 2: "FR", 3: "RL", 4: "FL"}
#: PX4 "Quadrotor x" (airframe reference): motor 1 front-right, 2 rear-left, 3 front-left,
#: 4 rear-right; CA_ROTORn is motor n + 1.
PX4 = {1: "FR", 2: "RL", 3: "FL", 4: "RR"}
#: An asymmetric frame (unequal arms and angles), and the paper's symmetric SY250.
FRAMES = {"SY250": [], "asymmetric": ["lambda_a_mm=140", "lambda_b_mm=110", "alpha_deg=80",
                                      "beta_deg=75"]}


@pytest.fixture(params=list(FRAMES))
def src(request):
    return source_of("SY250", overrides=FRAMES[request.param])


def test_the_table_holds_each_firmwares_numbering():
    for key, typed in (("betaflight", BETAFLIGHT), ("px4", PX4)):
        n = MOTOR_NUMBERING[key]
        assert {n.motor(i): ROTOR_LABELS[i] for i in range(4)} == typed
    assert rotor_label(3, "betaflight") == "RR (Betaflight motor 1)"
    assert rotor_label(0, "betaflight", "px4") == "FR (Betaflight motor 2, PX4 motor 1)"


def test_the_model_order_is_the_position_order(src):
    for i, r in enumerate(src.airframe.rotor_positions):
        assert position_of(r[0], r[1]) == ROTOR_LABELS[i]


def test_report_airframe_figure_labels_each_rotor_at_its_position(src):
    fig = plots.airframe_top_view([src.airframe], src.airframe)
    texts = [t for t in fig.axes[0].texts if t.get_text() in ROTOR_LABELS]
    assert sorted(t.get_text() for t in texts) == sorted(ROTOR_LABELS)
    for t in texts:
        right, forward = t.xyann if hasattr(t, "xyann") else t.get_position()
        assert position_of(forward, -right) == t.get_text()  # drawing: x = right, y = nose
    assert not [t for t in fig.axes[0].texts if t.get_text() in ("1", "2", "3", "4")]


def test_simulate_table_labels_each_rotor_at_its_position(cli_runner):
    from casadrone.cli import app

    res = cli_runner.invoke(app, ["simulate", "SY250", *FRAMES["asymmetric"]])
    assert res.exit_code == 0, res.output
    lines = res.stdout.splitlines()
    head = next(i for i, line in enumerate(lines) if line.split()[:1] == ["rotor"])
    assert "Betaflight motor" in lines[head] and "PX4 motor" in lines[head]
    rows = [line.split() for line in lines[head + 1:head + 5]]
    assert [r[0] for r in rows] == list(ROTOR_LABELS)
    for label, x, y, _spin, _hover, bf, px4 in rows:
        assert position_of(float(x), float(y)) == label
        assert BETAFLIGHT[int(bf)] == label and PX4[int(px4)] == label


MOTOR_LINE = re.compile(r"#\s+motor (\d) \(mmix (\d)\) = (\w\w) [a-z-]+ rotor, turning (CC?W) "
                        r"seen from above, at x=([-+\d.]+) mm forward, y=([-+\d.]+) mm left")


def test_betaflight_mix_names_each_motor_by_position(src):
    text = export(src, "betaflight")
    motors = [m.groups() for m in MOTOR_LINE.finditer(text)]
    assert len(motors) == 4
    mmix = {int(line.split()[1]): [float(v) for v in line.split()[2:]]
            for line in text.splitlines() if re.match(r"mmix \d ", line)}
    for n, k, label, _spin, x, y in motors:
        assert int(k) == int(n) - 1 and BETAFLIGHT[int(n)] == label
        assert position_of(float(x), float(y)) == label
        _, roll, pitch, _ = mmix[int(k)]
        # Betaflight's signs: roll + on the left motors, pitch + on the rear ones
        assert (roll > 0) == label.endswith("L") and (pitch > 0) == label.startswith("R")


def test_px4_rotor_geometry_names_each_rotor_by_position(src):
    text = export(src, "px4")
    params = {f[2]: float(f[3]) for f in (line.split("\t") for line in text.splitlines()
                                           if not line.startswith("#")) if len(f) == 5}
    notes = dict(re.findall(r"CA_ROTOR(\d) = motor \d = (\w\w) ", text))
    for n in range(4):
        x, y_right = params[f"CA_ROTOR{n}_PX"], params[f"CA_ROTOR{n}_PY"]
        label = position_of(x, -y_right)  # FRD: y to the right
        assert PX4[n + 1] == label and notes[str(n)] == label


def test_urdf_rotor_links_sit_at_their_positions(src, tmp_path):
    yourdfpy = pytest.importorskip("yourdfpy")
    path = tmp_path / "frame.urdf"
    path.write_text(export(src, "urdf"))
    robot = yourdfpy.URDF.load(str(path), load_meshes=False, build_scene_graph=False).robot
    rotors = {j.child: j.origin[:3, 3] for j in robot.joints if j.child.startswith("rotor_")}
    assert sorted(rotors) == sorted(f"rotor_{r}" for r in ROTOR_LABELS)
    for link, xyz in rotors.items():
        assert position_of(xyz[0], xyz[1]) == link.removeprefix("rotor_")


def test_svg_plate_labels_each_motor_at_its_position(src):
    root = ET.fromstring(export(src, "svg"))
    ns = {"s": "http://www.w3.org/2000/svg"}
    labels = [t for t in root.iterfind(".//s:text", ns) if t.get("class") == "rotor-label"]
    assert sorted(t.text for t in labels) == sorted(ROTOR_LABELS)
    for t in labels:
        right, nose = float(t.get("x")), -float(t.get("y"))  # SVG's y points down the page
        assert position_of(nose, -right) == t.text


def test_dxf_plate_labels_each_motor_at_its_position(src):
    ezdxf = pytest.importorskip("ezdxf")
    import io

    doc = ezdxf.read(io.StringIO(export(src, "dxf")))
    texts = [e for e in doc.modelspace().query("TEXT") if e.dxf.layer == "ROTORS"]
    assert sorted(e.dxf.text for e in texts) == sorted(ROTOR_LABELS)
    for e in texts:
        right, nose = e.dxf.insert[0], e.dxf.insert[1]
        assert position_of(nose, -right) == e.dxf.text
