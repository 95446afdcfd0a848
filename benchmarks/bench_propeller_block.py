"""Benchmark: what each term of the ``propeller`` model costs in the limit lap's interval blocks.

Why. A ``propeller`` limit-lap iteration costs 3.4× a ``paper`` one (benchmarks/
RESULTS-propulsion.md): twice the intervals, and an interval whose exact-Hessian block has
333 000 instructions against 143 000. Could the block be trimmed to ``paper``'s cost by
specialising the model, i.e. building it without the terms a given airframe switches off by a
parameter value (the first-order motor branch beside the DC motor, the pack's sag, the
positive/signed inflow switch), or is the cost in the physics itself?

What this measures: the instruction count of the compiled blocks' SX functions
(:func:`casadrone.limit.nlp.interval_block_functions`: the RK4 step's Hessian of λ·x_next and
its dense Jacobian, one interval, 3 RK4 steps) for the model as shipped and with one term taken
out of the symbolic model (the functions of :mod:`casadrone.propulsion` replaced in this
process only). The instruction count is what the generated C executes per interval: the
compiled blocks' time follows it (143 000 instructions: 10.3 ms for 160 blocks, 333 000:
~54 ms per iteration for 400 blocks; RESULTS-limitlap.md and RESULTS-propulsion.md). Nothing
is compiled.

Run: ``python benchmarks/bench_propeller_block.py`` (a markdown table on stdout, ~1 min).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: Each variant: what is taken out of the symbolic model, and the code that does it.
VARIANTS: dict[str, tuple[str, str]] = {
    "paper": ("the paper's Table 6 thrust model (for scale)", ""),
    "propeller": ("the model as shipped (DC motor, sag, CT/CP of the inflow, rotor drag)", ""),
    "no-first-order": (
        "the first-order motor branch (motor_dc fixed at 1)",
        "orig = PR.propeller_terms\n"
        "def terms(vel, omega, w, w_dot, u, q, r, s):\n"
        "    q = dict(q); q['motor_dc'] = 1.0\n"
        "    return orig(vel, omega, w, w_dot, u, q, r, s)\n"
        "PR.propeller_terms = terms; M.propeller_terms = terms\n"),
    "no-sag": ("the pack's sag (V_bat = V_oc)",
               "PR.battery_voltage = lambda w, u, q: q['batt_Voc']\n"),
    "positive-inflow-only": (
        "the signed-inflow switch (the smoothed max(v_a, 0) only)",
        "def inflow(v, q):\n"
        "    eps = q['inflow_eps']\n"
        "    return 0.5 * (v + ca.sqrt(v**2 + eps**2)) - 0.5 * eps\n"
        "PR.axial_inflow = inflow\n"),
    "specialised": (
        "both switches fixed at the shipped airframes' values (DC motor, positive inflow)",
        "orig = PR.propeller_terms\n"
        "def terms(vel, omega, w, w_dot, u, q, r, s):\n"
        "    q = dict(q); q['motor_dc'] = 1.0\n"
        "    return orig(vel, omega, w, w_dot, u, q, r, s)\n"
        "PR.propeller_terms = terms; M.propeller_terms = terms\n"
        "def inflow(v, q):\n"
        "    eps = q['inflow_eps']\n"
        "    return 0.5 * (v + ca.sqrt(v**2 + eps**2)) - 0.5 * eps\n"
        "PR.axial_inflow = inflow\n"),
    "no-inflow": ("the inflow altogether (static CT, CP: J = 0)",
                  "PR.axial_inflow = lambda v, q: 0 * v\n"),
}

_PROBE = """
import casadi as ca
import casadrone.model as M
import casadrone.propulsion.propeller as PR
from casadrone.limit import nlp as N
{patch}
model = N.quadrotor_ocp_model({kind!r})
jac, hess, _ = N.interval_block_functions(model, 3)
print(hess.n_instructions(), jac.n_instructions())
"""


def count(variant: str) -> tuple[int, int]:
    """(Hessian block, Jacobian block) instructions of ``variant``, in a fresh process (the
    model's functions are cached per process)."""
    kind = "paper" if variant == "paper" else "propeller"
    code = _PROBE.format(patch=VARIANTS[variant][1], kind=kind)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout.split()
    return int(out[-2]), int(out[-1])


def main() -> int:
    rows = ["| model | Hessian block (instructions) | against the shipped `propeller` | "
            "Jacobian block | against the shipped `propeller` |", "|---|---|---|---|---|"]
    base = count("propeller")
    for name, (what, _) in VARIANTS.items():
        h, j = base if name == "propeller" else count(name)
        rows.append(f"| {name}: {what} | {h} | {h / base[0]:.2f} | {j} | {j / base[1]:.2f} |")
    print("\n".join(["`python benchmarks/bench_propeller_block.py`", "", *rows]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
