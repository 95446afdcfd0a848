"""Evaluate one airframe: trim, linearise, design the LQR-I gain, fly the lap, read the indices.

Run: ``python examples/evaluate_airframe.py [AIRFRAME] [key=value ...]``
(e.g. ``python examples/evaluate_airframe.py HS210 beta_deg=80``).
"""

import sys

import casadrone as cd


def main(name: str = "SY250", overrides: list[str] | None = None) -> cd.Evaluation:
    cfg = cd.load_airframe(name, overrides)
    frame = cd.build_airframe(cfg)
    print(f"{cfg.name}: family {frame.family}, diagonal {frame.diagonal_mm:.0f} mm, "
          f"hover thrusts {frame.hover_thrusts().round(3)} N")

    # the stages one by one
    tp = cd.trim(frame, "hover", solver="newton")
    lin = cd.linearise(frame, tp)
    design = cd.design_lqri(lin, cd.load_controller())
    print(f"trim residual {tp.residual_norm:.1e}, closed loop stable: {design.stable} "
          f"(spectral radius {abs(design.closed_loop_eigenvalues).max():.5f})")

    # or the whole chain at once, on the paper track with the default controller
    ev = cd.evaluate(cd.theta_of(cfg), cd.default_setup(name), keep_trajectory=True)
    print(f"lap {ev.status} {ev.reason}")
    for key, value in ev.indices.items():
        idx = cd.INDICES[key]
        print(f"  {key} = {value:8.3f} {idx.unit:6s} ({idx.description})")
    for row in ev.intervals:
        print(f"  waypoint {row.waypoint}: split {row.split_time_s:6.2f} s, effort "
              f"{row.effort_V:+.3f} V, pair thrust {row.pair_thrust_max_N:+.2f}/"
              f"{row.pair_thrust_min_N:+.2f} N")
    return ev


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "SY250", sys.argv[2:])
