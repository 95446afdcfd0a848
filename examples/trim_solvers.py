"""Compare the three trim solvers on an asymmetric (hybrid) frame, in hover and forward flight.

Asymmetric frames trim with unequal rotor thrusts: the front/rear split follows from the arm
geometry. Run: ``python examples/trim_solvers.py``.
"""

import numpy as np

import casadrone as cd


def main() -> list:
    frame = cd.build_airframe(cd.load_airframe("HS210", ["lambda_a_mm=140", "lambda_b_mm=110"]))
    rows = []
    for condition, speed in (("hover", 0.0), ("forward", 10.0)):
        results = cd.trim_all(frame, condition, speed)
        print(f"\n{frame.name} (λa 140 mm, λb 110 mm, β 76°), {condition} {speed:g} m/s")
        print(f"{'solver':12s} {'ok':>3s} {'residual':>10s} {'iters':>6s} {'time ms':>8s}  "
              f"{'thrusts (N)':28s} pitch")
        for r in results:
            print(f"{r.solver:12s} {str(r.success):>3s} {r.residual_norm:10.1e} {r.iterations:6d} "
                  f"{r.wall_time_s * 1e3:8.2f}  {np.array2string(r.thrusts, precision=4):28s} "
                  f"{r.pitch_deg:5.2f}°")
        spread = max(np.abs(a.u0 - b.u0).max() for a in results for b in results)
        print(f"largest u0 disagreement between solvers: {spread:.1e}")
        rows.append(results)
    # the front/rear split from the pitch-moment balance, by hand
    x_front = 0.140 * np.cos(np.radians(45))
    x_rear = 0.110 * np.cos(np.radians(38))
    ratio = rows[0][0].thrusts[0] / rows[0][0].thrusts[2]
    print(f"\nhover front/rear thrust ratio: solver {ratio:.5f},"
          f" by hand x_rear/x_front = {x_rear / x_front:.5f}")
    return rows


if __name__ == "__main__":
    main()
