"""The shipped propeller's CT(J), CP(J) fit against its raw wind-tunnel points.

Loads ``casadrone/data/propulsion/uiuc-da4022-5x3.75-3blade.csv`` (UIUC Propeller Database,
Vol. 2), refits the quadratics on the points :func:`casadrone.propulsion.fit_points` selects,
prints the coefficients beside those in ``SY250-propeller.yaml`` with the largest relative
residual, and plots every raw point (all rpm) with the fit.

Run: ``python benchmarks/propeller_fit.py [--out docs/figures/propeller-fit.png]``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from casadrone.config import load_airframe  # noqa: E402
from casadrone.propulsion import (  # noqa: E402
    data_advance_ratio,
    fit_coefficients,
    fit_points,
    propeller_data,
)
from casadrone.propulsion.propeller import coefficients  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent.parent / "docs"
                                         / "figures" / "propeller-fit.png"))
    a = ap.parse_args()
    data = propeller_data()
    pts = fit_points(data)
    cfg = load_airframe("SY250-propeller")
    shipped = coefficients(cfg.propulsion, cfg.air_density_kgm3)
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9.0, 4.5), layout="constrained")
    axes = fig.subplots(1, 2)
    Jf = np.linspace(0, 0.9, 200)
    for ax, col, name, ship in zip(axes, (2, 3), ("CT", "CP"), shipped, strict=True):
        c = fit_coefficients(pts[:, 0], pts[:, col])
        res = np.polynomial.polynomial.polyval(pts[:, 0], c) - pts[:, col]
        print(f"{name}: refit {np.round(c, 5).tolist()}, shipped {ship}, largest residual "
              f"{np.max(np.abs(res)):.4f} ({100 * np.max(np.abs(res)) / c[0]:.1f} % of the static "
              f"value) over {len(pts)} points")
        for rpm in np.unique(data[data[:, 0] > 0, 1]):
            sel = (data[:, 1] == rpm) & (data[:, 0] > 0)
            ax.plot(data[sel, 0], data[sel, col], "o", ms=3, label=f"tunnel, {rpm:.0f} rpm")
        st = data[:, 0] == 0
        ax.plot(data[st, 0], data[st, col], "k.", ms=4, label="static, 1570-6950 rpm")
        ax.plot(pts[:, 0], pts[:, col], "kx", ms=6, label="points fitted")
        ax.plot(Jf, np.polynomial.polynomial.polyval(Jf, ship), "r-", lw=1.5,
                label="shipped quadratic")
        ax.axvline(data_advance_ratio(), color="grey", ls=":", lw=0.8)
        ax.set_xlabel("advance ratio J = V/(nD)")
        ax.set_ylabel(name)
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle("UIUC DA4022 5.0x3.75, 3 blades: CT(J), CP(J) points and the shipped fit")
    fig.savefig(a.out, dpi=110)
    print(f"figure: {a.out}")


if __name__ == "__main__":
    main()
