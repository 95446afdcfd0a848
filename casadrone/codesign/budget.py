"""A CPU budget for one IPOPT solve, set per call on a solver built once.

IPOPT's own ``max_cpu_time`` is an option, fixed when the solver is built; the continuation's
steps need a budget that follows the front (:func:`casadrone.codesign.front.design_front`: a
few times the slowest converged step). :class:`CpuBudget` is the solver's iteration callback
(CasADi's ``iteration_callback``): at each iteration it compares the CPU seconds of this process
since :meth:`CpuBudget.start` with the budget and, past it, asks IPOPT to stop
(``User_Requested_Stop``). It reads nothing of the iterate, so it does not change the solver's
path: a solve within its budget is bit-identical to one without the callback.
"""

from __future__ import annotations

import math
import time

import casadi as ca

#: IPOPT's return status when the callback stopped it (CasADi's name for it).
STOPPED = "User_Requested_Stop"


class CpuBudget(ca.Callback):
    """Iteration callback of a solver with ``nx`` variables, ``ng`` rows and ``np`` parameters;
    unlimited until :meth:`start` is given a budget."""

    def __init__(self, name: str, nx: int, ng: int, np_: int):
        ca.Callback.__init__(self)
        self._sizes = {"x": nx, "lam_x": nx, "g": ng, "lam_g": ng, "lam_p": np_, "f": 1}
        self.limit_s = math.inf
        self._t0 = 0.0
        self.construct(name, {})

    def start(self, limit_s: float | None) -> None:
        """Count from now; ``None``: no budget."""
        self.limit_s = math.inf if limit_s is None else float(limit_s)
        self._t0 = time.process_time()

    def spent(self) -> float:
        return time.process_time() - self._t0

    # CasADi's Callback interface: the solver's outputs in, one flag out (1: stop)
    def get_n_in(self) -> int:
        return ca.nlpsol_n_out()

    def get_n_out(self) -> int:
        return 1

    def get_name_in(self, i: int) -> str:
        return ca.nlpsol_out(i)

    def get_name_out(self, i: int) -> str:
        return "stop"

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return ca.Sparsity.dense(self._sizes[ca.nlpsol_out(i)], 1)

    def eval(self, arg):
        return [1 if self.spent() > self.limit_s else 0]
