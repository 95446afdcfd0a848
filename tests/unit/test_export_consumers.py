"""Exports loaded by the tools that consume them (issue 20, points 9 and 10): the URDF in pybullet
(mass, hover at hover thrust, collision with the ground) and summed link by link by a third-party
parser (yourdfpy), the PX4 file by QGroundControl's reading rules (see test_export.qgc_rows)."""

from __future__ import annotations

import numpy as np
import pytest

from casadrone.export import write_export
from casadrone.export.source import source_of

FRAMES = ("SY250", "HS210", "NSY200", "SY250-components")


@pytest.fixture
def bullet():
    p = pytest.importorskip("pybullet")
    client = p.connect(p.DIRECT)
    yield p, client
    p.disconnect(client)


def load(p, client, src, tmp_path, height: float):
    path = write_export(src, "urdf", tmp_path / f"{src.config.name}.urdf")
    p.setGravity(0, 0, -src.airframe.gravity, physicsClientId=client)
    p.setTimeStep(1 / 240, physicsClientId=client)
    # the loading flag the README and the file state: inertia from the file, not the shapes
    return p.loadURDF(str(path), basePosition=[0, 0, height], physicsClientId=client,
                      flags=p.URDF_USE_INERTIA_FROM_FILE)


def fly(p, client, body, thrusts, seconds: float = 1.0) -> np.ndarray:
    """Step pybullet with each rotor link pushed along its own z axis; the base's centre of mass
    after ``seconds``."""
    for _ in range(round(240 * seconds)):
        for i, t in enumerate(thrusts):
            p.applyExternalForce(body, i, [0, 0, float(t)], [0, 0, 0], p.LINK_FRAME,
                                 physicsClientId=client)
        p.stepSimulation(physicsClientId=client)
    return np.array(p.getBasePositionAndOrientation(body, physicsClientId=client)[0])


@pytest.mark.parametrize("frame", FRAMES)
def test_urdf_hovers_in_pybullet_at_hover_thrust(bullet, tmp_path, frame):
    p, client = bullet
    src = source_of(frame)
    body = load(p, client, src, tmp_path, 1.0)
    n = p.getNumJoints(body, physicsClientId=client)
    masses = [p.getDynamicsInfo(body, i, physicsClientId=client)[0] for i in range(-1, n)]
    assert n == 4 and sum(masses) == pytest.approx(src.airframe.mass, rel=1e-9)
    names = [p.getJointInfo(body, i, physicsClientId=client)[12].decode() for i in range(n)]
    assert names == ["rotor_FR", "rotor_FL", "rotor_RL", "rotor_RR"]
    start = np.array(p.getBasePositionAndOrientation(body, physicsClientId=client)[0])
    end = fly(p, client, body, src.airframe.hover_thrusts())
    drift = np.linalg.norm(end - start)
    assert drift <= 1e-3  # the bar; observed <= 3e-10 m
    # and the thrust is what holds it: 10 % less and it sinks ~ g/20 s² = 0.5 m·s⁻²·(1 s)²/2
    p.resetBasePositionAndOrientation(body, start.tolist(), [0, 0, 0, 1], physicsClientId=client)
    p.resetBaseVelocity(body, [0, 0, 0], [0, 0, 0], physicsClientId=client)
    sunk = start[2] - fly(p, client, body, 0.9 * src.airframe.hover_thrusts())[2]
    assert sunk == pytest.approx(0.1 * src.airframe.gravity / 2, rel=0.05)


def test_urdf_rests_on_the_ground_through_its_collision_shapes(bullet, tmp_path):
    p, client = bullet
    ground = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=client)
    p.createMultiBody(0, ground, physicsClientId=client)
    body = load(p, client, source_of("SY250"), tmp_path, 0.05)
    end = fly(p, client, body, [0.0] * 4, seconds=1.0)
    assert 0.0 < end[2] < 0.05  # landed, not fallen through (no collision shape: z -> -4.9 m)


def composite(robot) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass, centre of mass and inertia about it of every link of a yourdfpy model whose links
    hang off base_link by fixed-origin joints (parallel-axis theorem, independent of casadrone)."""
    offset = {j.child: j.origin[:3, 3] for j in robot.joints}
    parts = []
    for link in robot.links:
        if link.inertial is None:
            continue
        rot = link.inertial.origin[:3, :3]
        at = offset.get(link.name, np.zeros(3)) + link.inertial.origin[:3, 3]
        parts.append((link.inertial.mass, at, rot @ np.asarray(link.inertial.inertia) @ rot.T))
    m = sum(pm for pm, _, _ in parts)
    c = sum(pm * at for pm, at, _ in parts) / m
    J = sum(Jc + pm * (np.dot(at - c, at - c) * np.eye(3) - np.outer(at - c, at - c))
            for pm, at, Jc in parts)
    return m, c, J


@pytest.mark.parametrize("frame", FRAMES)
def test_urdf_links_sum_to_the_airframe(frame, tmp_path):
    yourdfpy = pytest.importorskip("yourdfpy")
    src = source_of(frame)
    path = write_export(src, "urdf", tmp_path / "f.urdf")
    robot = yourdfpy.URDF.load(str(path), load_meshes=False, build_scene_graph=False).robot
    assert all(link.inertial is not None for link in robot.links)
    assert all(link.collisions for link in robot.links)
    m, c, J = composite(robot)
    assert m == pytest.approx(src.airframe.mass, rel=1e-9)
    np.testing.assert_allclose(c, 0.0, atol=1e-9)  # base_link's origin is the centre of mass
    np.testing.assert_allclose(J, src.airframe.inertia, rtol=0, atol=1e-8 * np.abs(
        src.airframe.inertia).max())  # 9 digits written; observed <= 3.6e-9 relative


def test_a_build_winners_urdf_weighs_the_build_mass_in_pybullet(bullet, tmp_path):
    """A build's winner (its parts at a co-designed geometry, as ``casadrone build`` writes
    winner.yaml: :func:`casadrone.build.search.winner_airframe`) loads in pybullet with the
    build's mass: the links' masses sum to the mass the build reports (that of its airframe)."""
    from casadrone.airframe import build_airframe
    from casadrone.build.checks import load_build_problem
    from casadrone.build.search import screened, winner_airframe
    from casadrone.build.solve import BuildResult
    from casadrone.export.source import ExportSource

    p, client = bullet
    problem = load_build_problem("build-small")
    combo = screened(problem)[0][1]  # the DA4022 with the 1750 KV motor and the 4S 1300 mAh
    won = BuildResult(combo, "raced", theta={"lambda_a_mm": 104.0, "lambda_b_mm": 131.0})
    cfg = winner_airframe(problem, (won,))
    assert cfg is not None and cfg.lambda_a_mm == 104.0 and cfg.lambda_b_mm == 131.0
    frame = build_airframe(cfg)
    body = load(p, client, ExportSource(cfg, frame, "build", combo.label), tmp_path, 1.0)
    links = range(-1, p.getNumJoints(body, physicsClientId=client))
    total = sum(p.getDynamicsInfo(body, i, physicsClientId=client)[0] for i in links)
    assert total == pytest.approx(frame.mass, rel=1e-6)
    # the co-designed geometry is in it: shorter arms weigh less (components mass model)
    assert frame.mass > build_airframe(cfg.model_copy(update={"lambda_a_mm": 100.0})).mass
