"""Figures carry the data they are given, label their units and save as PNG and SVG."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from matplotlib.patches import Circle

from casadrone import plots
from casadrone.airframe import build_airframe
from casadrone.config.airframe import load_airframe
from casadrone.config.controller import ControllerConfig
from casadrone.control import design_for, disturbance_response, robustness_ensemble
from casadrone.model import IDX
from casadrone.simulate import Trajectory

V_BATT = 14.8
U0 = np.array([0.09, 0.10, 0.11, 0.12])
WAYPOINTS = np.array([[10.0, 0.0, 5.0], [10.0, 2.0, 5.0], [0.0, 2.0, 5.0]])


def fake_trajectory(n: int = 60, shift: float = 0.0) -> Trajectory:
    """A hand-made flight: a loop at 5 m with known commands and thrusts."""
    t = np.arange(n) * 0.01
    s = np.linspace(0, 2 * np.pi, n)
    x = np.zeros((n, 16))
    x[:, 0], x[:, 1], x[:, 2] = 5 + 5 * np.cos(s) + shift, 1 + np.sin(s), 5 + 0.1 * s
    x[:, 3], x[:, 4], x[:, 5] = 3.0, 4.0, 0.0  # |v| = 5 m/s
    x[:, 12:16] = [1.0, 1.5, 2.5, 0.5]  # (T2 + T3) − (T1 + T4) = 2.5 N
    u = np.tile(U0, (n, 1))
    u[:, 1] += 0.05  # left rotors 2 and 3 above trim by 0.05 and 0.03: roll effort 0.04 V_batt
    u[:, 2] += 0.03
    return Trajectory(
        status="completed", reason="", integrator="rk4", t=t, x=x, u=u, p_ref=x[:, :3],
        v_ref=np.zeros((n, 3)), psi_ref=np.zeros(n), acceleration=np.zeros((n, 3)),
        segment=np.zeros(n, int), u0=U0, battery_voltage=V_BATT, waypoints=WAYPOINTS,
        straight=(True, False, True), split_times=np.array([0.1, 0.25, np.nan]),
    )


@pytest.fixture(scope="module")
def sy250():
    return build_airframe(load_airframe("SY250"))


@pytest.fixture(scope="module")
def design_ensemble(sy250):
    ctrl = ControllerConfig()
    design = design_for(sy250, ctrl)
    return design, robustness_ensemble(sy250, design, ctrl, 3)


def by_gid(ax, gid):
    return [line for line in ax.get_lines() if line.get_gid() == gid]


def assert_units(*labels):
    for label in labels:
        assert "(" in label and label.rstrip().endswith(")"), f"no unit in {label!r}"


def test_track_top_view_plots_each_trajectory_and_numbered_waypoints():
    trs = {"A": fake_trajectory(), "B": fake_trajectory(shift=1.0)}
    fig = plots.track_top_view(trs, WAYPOINTS)
    assert isinstance(fig, Figure)
    (ax,) = fig.axes
    for name, tr in trs.items():
        (line,) = by_gid(ax, f"track:{name}")
        np.testing.assert_array_equal(line.get_xdata(), tr.x[:, 0])
        np.testing.assert_array_equal(line.get_ydata(), tr.x[:, 1])
    (wp,) = by_gid(ax, "waypoints")
    drawn = np.column_stack([wp.get_xdata(), wp.get_ydata()])
    np.testing.assert_array_equal(drawn, WAYPOINTS[:, :2])
    assert [t.get_text() for t in ax.texts] == ["WP1", "WP2", "WP3"]
    assert ax.get_aspect() == 1.0
    assert "(m)" in ax.get_xlabel() and "(m)" in ax.get_ylabel()
    assert len(ax.get_legend().get_texts()) == 3


def test_track_top_view_draws_into_a_given_axes():
    host = Figure()
    ax = host.add_subplot()
    assert plots.track_top_view({"A": fake_trajectory()}, ax=ax) is host
    (line,) = by_gid(ax, "track:A")
    np.testing.assert_array_equal(line.get_xdata(), fake_trajectory().x[:, 0])


def test_trajectory_3d_plots_the_flight_path():
    tr = fake_trajectory()
    fig = plots.trajectory_3d({"A": tr}, WAYPOINTS)
    (ax,) = fig.axes
    (line,) = by_gid(ax, "track:A")
    np.testing.assert_array_equal(np.array(line.get_data_3d()).T, tr.x[:, :3])
    for label in (ax.get_xlabel(), ax.get_ylabel(), ax.get_zlabel()):
        assert "(m)" in label


def test_time_histories_stack_four_signals_with_split_lines():
    tr = fake_trajectory()
    fig = plots.time_histories({"A": tr})
    assert len(fig.axes) == 4
    # roll effort ((δ2 + δ3) − (δ1 + δ4))/2 · V_batt minus trim; thrust (T2 + T3) − (T1 + T4)
    units = ["(m)", "(m/s)", "(V)", "(N)"]
    expected = [tr.x[:, IDX["z"]], np.full(len(tr.t), 5.0), np.full(len(tr.t), 0.04 * V_BATT),
                np.full(len(tr.t), 2.5)]
    for ax, unit, y in zip(fig.axes, units, expected, strict=True):
        assert unit in ax.get_ylabel()
        (line,) = by_gid(ax, "signal:A")
        np.testing.assert_array_equal(line.get_xdata(), tr.t)
        np.testing.assert_allclose(line.get_ydata(), y, rtol=1e-12)
        verticals = sorted(ln.get_xdata()[0] for ln in ax.get_lines()
                           if ln.get_linestyle() == "--")
        np.testing.assert_allclose(verticals, [0.1, 0.25])  # the NaN split is not drawn
    assert "(s)" in fig.axes[-1].get_xlabel()


def test_eigenvalue_cloud_shows_nominal_and_ensemble_inside_the_unit_circle(design_ensemble):
    design, ens = design_ensemble
    fig = plots.eigenvalue_cloud(design, ens)
    assert len(fig.axes) == 2  # whole disc + zoom near z = 1
    for ax in fig.axes:
        (nom,) = by_gid(ax, "nominal")
        np.testing.assert_array_equal(nom.get_xdata(), design.closed_loop_eigenvalues.real)
        np.testing.assert_array_equal(nom.get_ydata(), design.closed_loop_eigenvalues.imag)
        (cloud,) = by_gid(ax, "ensemble")
        np.testing.assert_array_equal(cloud.get_xdata(), ens.eigenvalues.ravel().real)
        assert len(cloud.get_xdata()) == 3 * 20
        (circle,) = by_gid(ax, "unit-circle")
        np.testing.assert_allclose(np.hypot(circle.get_xdata(), circle.get_ydata()), 1.0)
        assert "(–)" in ax.get_xlabel() and "(–)" in ax.get_ylabel()
    zoom = fig.axes[1]
    slowest = design.closed_loop_eigenvalues[np.argmax(np.abs(design.closed_loop_eigenvalues))]
    lo, hi = zoom.get_xlim()
    assert lo < slowest.real < hi and hi > 1.0 and hi - lo < 0.5


def test_eigenvalue_cloud_single_panel_with_explicit_zoom(design_ensemble):
    design, _ = design_ensemble
    fig = plots.eigenvalue_cloud(design, zoom=False)
    assert len(fig.axes) == 1
    host = Figure()
    ax = host.add_subplot()
    plots.eigenvalue_cloud(design, ax=ax, zoom=(0.9, 1.01, -0.05, 0.05))
    np.testing.assert_allclose(ax.get_xlim(), (0.9, 1.01))
    np.testing.assert_allclose(ax.get_ylim(), (-0.05, 0.05))


def test_disturbance_responses_grid_matches_linear_responses(design_ensemble):
    design, ens = design_ensemble
    fig = plots.disturbance_responses(design, ens, horizon_s=2.0)
    assert len(fig.axes) == 12
    dx0 = plots.default_bump()
    assert np.flatnonzero(dx0).tolist() == sorted(IDX[n] for n in ("u", "w", "p", "q"))
    steps = 201
    nominal = disturbance_response(design.Ad, design.Bd, design.K, dx0, steps)
    perturbed = [disturbance_response(A, B, design.K, dx0, steps) for A, B in ens.plants]
    for ax, (state, ylabel, scale) in zip(fig.axes, plots.B1_PANELS, strict=True):
        assert ax.get_ylabel() == ylabel
        assert_units(ylabel)
        (nom,) = by_gid(ax, "nominal")
        np.testing.assert_allclose(nom.get_xdata(), np.arange(steps) * design.sample_time_s)
        np.testing.assert_allclose(nom.get_ydata(), scale * nominal[:, IDX[state]], rtol=1e-12)
        grey = by_gid(ax, "ensemble")
        assert len(grey) == 3
        for line, resp in zip(grey, perturbed, strict=True):
            np.testing.assert_allclose(line.get_ydata(), scale * resp[:, IDX[state]], rtol=1e-12)
    assert [a.get_ylabel() for a in fig.axes[:4]] == ["u (m/s)", "v (m/s)", "w (m/s)", "p (deg/s)"]
    assert "(s)" in fig.axes[-1].get_xlabel()


def test_disturbance_responses_show_an_unexcited_state_flat(design_ensemble):
    design, _ = design_ensemble
    dx0 = np.zeros(20)
    dx0[IDX["w"]] = 1.0  # a vertical bump excites no yaw
    fig = plots.disturbance_responses(design, dx0=dx0, horizon_s=1.0)
    r_axes = fig.axes[5]
    assert r_axes.get_ylabel() == "r (deg/s)"
    np.testing.assert_allclose(r_axes.get_ylim(), (-plots.MIN_SPAN, plots.MIN_SPAN))


def test_airframe_top_view_puts_rotors_where_the_airframe_has_them(sy250):
    skewed = dataclasses.replace(
        sy250, name="skewed",
        rotor_positions=np.array([[0.12, -0.07, 0.0], [0.10, 0.09, 0.0],
                                  [-0.08, 0.11, 0.0], [-0.13, -0.06, 0.0]]))
    fig = plots.airframe_top_view([skewed, sy250], reference=sy250, prop_diameter_m=0.127)
    assert len(fig.axes) == 2
    ax = fig.axes[0]
    (rotors,) = by_gid(ax, "rotors:skewed")
    drawn = np.column_stack([rotors.get_xdata(), rotors.get_ydata()])
    r = skewed.rotor_positions
    np.testing.assert_allclose(drawn, 1000 * np.column_stack([-r[:, 1], r[:, 0]]), rtol=1e-12)
    assert drawn[0, 0] > 0 and drawn[0, 1] > 0  # rotor 1 (front-right) drawn right of and above CoM
    (ref,) = by_gid(ax, f"rotors:{sy250.name}")
    np.testing.assert_allclose(ref.get_xdata(), -1000 * sy250.rotor_positions[:, 1])
    discs = [p for p in ax.patches if isinstance(p, Circle)]
    assert len(discs) == 8
    np.testing.assert_allclose([d.get_radius() for d in discs], 63.5)
    dashed = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
    assert len(dashed) == 4  # the reference's arms
    assert "(mm)" in ax.get_xlabel() and "(mm)" in ax.get_ylabel()
    overlay = plots.airframe_top_view([skewed, sy250], reference=sy250, overlay=True)
    assert len(overlay.axes) == 1


def test_pareto_front_two_objectives_scatter_and_highlights():
    F = np.array([[14.0, 5.0], [15.0, 7.0], [16.0, 8.5], [17.0, 9.0]])
    fig = plots.pareto_front(F, ["J3", "J1"], {"utopian": 1, "extreme J3": 0}, units=["s", "m/s"])
    (ax,) = fig.axes
    front = next(c for c in ax.collections if c.get_gid() == "front")
    np.testing.assert_array_equal(front.get_offsets(), F)
    utopian = next(c for c in ax.collections if c.get_gid() == "highlight:utopian")
    np.testing.assert_array_equal(utopian.get_offsets(), F[[1]])
    assert {t.get_text() for t in ax.texts} == {"utopian", "extreme J3"}
    assert ax.get_xlabel() == "J3 (s)" and ax.get_ylabel() == "J1 (m/s)"


def test_pareto_front_scatter_matrix_shows_every_pair_once():
    rng = np.random.default_rng(1)
    F = rng.uniform(size=(12, 4))
    names, units = ["J1", "J3", "J5", "Jp"], ["m/s", "s", "V", "deg"]
    fig = plots.pareto_front(F, names, {"compromise": 5}, units=units)
    assert len(fig.axes) == 6
    pairs = set()
    for ax in fig.axes:
        i = names.index(ax.get_xlabel().split(" ")[0])
        j = names.index(ax.get_ylabel().split(" ")[0])
        assert_units(ax.get_xlabel(), ax.get_ylabel())
        front = next(c for c in ax.collections if c.get_gid() == "front")
        np.testing.assert_array_equal(front.get_offsets(), F[:, [i, j]])
        pairs.add((i, j))
    assert pairs == {(i, j) for i in range(4) for j in range(4) if i < j}
    with pytest.raises(ValueError, match="3 names for 4 objectives"):
        plots.pareto_front(F, names[:3])


def test_a_candidate_has_one_colour_in_the_pareto_front_and_the_top_views(sy250):
    F = np.array([[14.0, 5.0], [15.0, 7.0], [16.0, 8.5], [17.0, 9.0]])
    rows = {"A": 1, "B": 2, "C": 0}
    titles = {k: f"{k}: decision {k}" for k in rows}
    front = plots.pareto_front(F, ["J3", "J1"], rows, units=["s", "m/s"],
                               colours={k: plots.candidate_colour(k) for k in rows},
                               descriptions=titles)
    (ax,) = front.axes
    # the points carry the short label, the legend the description
    assert {t.get_text() for t in ax.texts} == set(rows)
    assert {t.get_text() for t in ax.get_legend().get_texts()} == {"Pareto front", *titles.values()}
    flights = {titles[k]: fake_trajectory(shift=i) for i, k in enumerate(rows)}
    top = plots.track_top_view(flights, colours={titles[k]: plots.candidate_colour(k)
                                                 for k in rows})
    frames = [dataclasses.replace(sy250, name=f"Candidate {k}") for k in rows]
    airframes = plots.airframe_top_view(frames, colours={f"Candidate {k}": plots.candidate_colour(k)
                                                         for k in rows})
    for k in rows:
        ring = next(c for c in ax.collections if c.get_gid() == f"highlight:{k}")
        (track,) = by_gid(top.axes[0], f"track:{titles[k]}")
        (rotors,) = [line for a in airframes.axes for line in by_gid(a, f"rotors:Candidate {k}")]
        colour = to_rgba(plots.candidate_colour(k))
        assert tuple(ring.get_edgecolor()[0]) == colour
        assert to_rgba(track.get_color()) == colour
        assert to_rgba(rotors.get_color()) == colour
    # one colour per candidate, never the front's own C0 (NOMINAL)
    colours = [to_rgba(plots.candidate_colour(k)) for k in rows]
    assert len(set(colours)) == 3 and to_rgba(plots.NOMINAL) not in colours
    assert plots.candidate_colour("A=C") == plots.candidate_colour("A")
    for bad in ("utopian", "extreme", "Z"):
        with pytest.raises(ValueError, match="expected a letter"):
            plots.candidate_colour(bad)


def test_convergence_plots_hypervolume_and_archive_size():
    g = np.arange(6)
    hv, size = np.linspace(0.1, 0.6, 6), np.array([3, 4, 6, 6, 7, 7])
    fig = plots.convergence(g, hv, size)
    assert len(fig.axes) == 2
    (hv_line,) = by_gid(fig.axes[0], "hypervolume")
    np.testing.assert_array_equal(hv_line.get_ydata(), hv)
    (size_line,) = by_gid(fig.axes[1], "archive")
    np.testing.assert_array_equal(size_line.get_xdata(), g)
    np.testing.assert_array_equal(size_line.get_ydata(), size)
    assert "(designs)" in fig.axes[1].get_ylabel() and "(–)" in fig.axes[1].get_xlabel()
    assert len(plots.convergence(g, hv).axes) == 1


def test_save_figure_writes_png_and_svg(tmp_path):
    fig = plots.convergence([0, 1, 2], [0.1, 0.2, 0.25])
    paths = plots.save_figure(fig, tmp_path / "plots" / "convergence")
    assert [p.name for p in paths] == ["convergence.png", "convergence.svg"]
    png, svg = (p.read_bytes() for p in paths)
    assert png.startswith(b"\x89PNG\r\n\x1a\n") and len(png) > 1000
    assert b"<svg" in svg[:1000] and svg.rstrip().endswith(b"</svg>")


def test_save_figure_keeps_what_lies_outside_the_canvas(tmp_path):
    # a label below the canvas (as a long x label can be at 150 dpi) is kept: the PNG grows to
    # the tight bounding box instead of clipping it
    from matplotlib.figure import Figure
    from matplotlib.image import imread

    from casadrone.plots import PAD_INCHES, save_figure

    def ink(label: bool) -> tuple[np.ndarray, int]:
        fig = Figure(figsize=(4.0, 3.0))
        fig.add_subplot().plot([0, 1], [0, 1])
        if label:
            fig.text(0.5, -0.2, "a bottom label", ha="center", va="top", fontsize=14)
        (png,) = save_figure(fig, tmp_path / f"f{label}", formats=("png",), dpi=100)
        img = imread(png)[..., :3]
        return img, int((img < 0.5).any(axis=2).sum())

    img, with_label = ink(True)
    _, without = ink(False)
    assert with_label > without + 100  # the label's pixels are in the PNG
    ink_rows = np.flatnonzero((img < 0.5).any(axis=(1, 2)))
    assert img.shape[0] - 1 - ink_rows.max() >= PAD_INCHES * 100 - 2  # white pad below the label
