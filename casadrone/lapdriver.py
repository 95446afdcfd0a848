"""The whole RK4 closed-loop lap in one C call, stopped at the sample where it ends.

CasADi generates C for one sample of the closed loop (the ``step`` Function of
:mod:`casadrone.simulate`: guidance, LQR-I, RK4 plant); a short hand-written C loop
(:data:`DRIVER_C`) calls it sample after sample, stores every sample into caller-owned numpy
arrays, and checks after each one what :func:`casadrone.simulate.simulate` checks: non-finite
state, attitude beyond the track's limit, ground strike (after having been airborne), the last
waypoint reached, the time limit. One Python → C crossing per lap instead of one per chunk, and
no sample computed past the lap's end. The sample is the same generated code that the chunked
``mapaccum`` path runs, so the trajectory is the same to the last bit (tested).
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass

import casadi as ca
import numpy as np

from casadrone.codegen import casadi_source, compile_source

#: How a lap ended (index = the code the C loop returns).
OUTCOMES = ("completed", "non-finite", "attitude", "ground", "time-out", "error")

DRIVER_C = r"""
/* ---- casadrone lap driver: the closed loop of STEP, sample by sample, to the lap's end ---- */
#include <math.h>
/* in: x (NXS), c (NCS), then the step's remaining inputs, concatenated (column-major).
   lim: n_seg, start height z0 (m), tilt limit (rad), ground margin (m), n_max (samples).
   X, C, U, R: n_max rows each (state at t[k]; controller state, command, log after sample k).
   out: [samples kept, outcome code]. */
CASADI_SYMBOL_EXPORT int casadrone_lap(const casadi_real* in, const casadi_real* lim,
                                       casadi_real* X, casadi_real* C, casadi_real* U,
                                       casadi_real* R, long long* out) {
  const casadi_real* arg[SZ_ARG];
  casadi_real* res[SZ_RES];
  casadi_int iw[SZ_IW + 1];
  casadi_real w[SZ_W + 1];
  casadi_real x[NXS], xn[NXS];
  const casadi_real* c = in + NXS;
  const casadi_real n_seg = lim[0], z0 = lim[1], tilt = lim[2], margin = lim[3];
  const long long n_max = (long long)lim[4];
  long long k;
  int i, airborne = 0;
  for (i = 0; i < NXS; ++i) x[i] = in[i];
  for (k = 0; k < n_max; ++k) {
    casadi_real* xk = X + k * NXS;
    int finite = 1;
    for (i = 0; i < NXS; ++i) xk[i] = x[i];
    arg[0] = x;
    arg[1] = c;
    OTHER_ARGS
    res[0] = xn;
    res[1] = C + k * NCS;
    res[2] = U + k * NUS;
    res[3] = R + k * NRS;
    if (STEP(arg, res, iw, w, 0)) { out[0] = k + 1; out[1] = 5; return 1; }
    for (i = 0; i < NXS; ++i) finite = finite && isfinite(xk[i]);
    if (!finite) { out[0] = k + 1; out[1] = 1; return 0; }
    if (fabs(xk[9]) > tilt || fabs(xk[10]) > tilt) { out[0] = k + 1; out[1] = 2; return 0; }
    if (xk[2] - z0 > 1.0) airborne = 1;
    if (xk[2] < z0 - margin || (airborne && xk[2] < z0)) { out[0] = k + 1; out[1] = 3; return 0; }
    if (C[k * NCS + 4] > n_seg - 0.5) { out[0] = k + 1; out[1] = 0; return 0; }
    for (i = 0; i < NXS; ++i) x[i] = xn[i];
    c = C + k * NCS;
  }
  out[0] = n_max;
  out[1] = 4;
  return 0;
}
"""


def driver_source(step: ca.Function) -> str:
    """C of ``step`` (inputs x, c, …; outputs x_next, c_next, u, ref) plus the lap loop."""
    offsets, other = step.nnz_in(0) + step.nnz_in(1), []
    for i in range(2, step.n_in()):
        other.append(f"arg[{i}] = in + {offsets};")
        offsets += step.nnz_in(i)
    defs = {
        "STEP": step.name(), "SZ_ARG": step.sz_arg(), "SZ_RES": step.sz_res(),
        "SZ_IW": step.sz_iw(), "SZ_W": step.sz_w(), "NXS": step.nnz_in(0),
        "NCS": step.nnz_in(1), "NUS": step.nnz_out(2), "NRS": step.nnz_out(3),
    }
    body = DRIVER_C.replace("OTHER_ARGS", "\n    ".join(other))
    head = "".join(f"\n#define {k} {v}" for k, v in defs.items())
    return casadi_source(step, head + "\n" + body)


@dataclass(frozen=True)
class LapRun:
    """A lap from the driver: ``n`` samples kept (rows of X, C, U, R) and how it ended."""

    n: int
    outcome: str
    X: np.ndarray
    C: np.ndarray
    U: np.ndarray
    R: np.ndarray


class LapDriver:
    """The compiled lap loop of a ``step`` Function, called through ctypes."""

    def __init__(self, step: ca.Function):
        self.sizes = [step.nnz_in(i) for i in range(step.n_in())]
        self.widths = [step.nnz_out(i) for i in range(step.n_out())]
        path = compile_source(f"{step.name()}_driver", driver_source(step))
        self.lib = ctypes.CDLL(str(path))
        self.fn = self.lib.casadrone_lap
        self.fn.restype = ctypes.c_int
        self.fn.argtypes = [ctypes.c_void_p] * 7

    def run(self, inputs, n_seg: int, z0: float, tilt_rad: float, margin: float,
            n_max: int) -> LapRun:
        """Fly from ``inputs`` = (x, c, p, x0, u0, K, g) for at most ``n_max`` samples."""
        packed = np.concatenate([np.asarray(a, float).ravel(order="F") for a in inputs])
        if packed.size != sum(self.sizes):
            raise ValueError(f"lap inputs: {packed.size} values, expected {sum(self.sizes)}")
        lim = np.array([n_seg, z0, tilt_rad, margin, n_max], float)
        nx, nc, nu, nr = self.widths
        X, C, U, R = (np.empty((n_max, w)) for w in (nx, nc, nu, nr))
        out = np.zeros(2, dtype=np.int64)  # per call: a driver may be shared by threads
        self.fn(packed.ctypes.data, lim.ctypes.data, X.ctypes.data, C.ctypes.data,
                U.ctypes.data, R.ctypes.data, out.ctypes.data)
        n, code = int(out[0]), int(out[1])
        return LapRun(n=n, outcome=OUTCOMES[code], X=X[:n], C=C[:n], U=U[:n], R=R[:n])
