"""A Ctrl-C that lands inside a CasADi solve still stops a run.

CasADi calls Python's signal handlers from inside a solve and turns the exception they raise
into a warning and a normal return, so the run's :class:`Interrupted` would be lost and the
run would go on (seen as a flaky exit 0 of the Ctrl-C test). The oracle is CasADi itself: a
real IPOPT solve is interrupted by a real SIGINT; the solve returns without raising, and the
run's check raises :class:`Interrupted` afterwards.
"""

from __future__ import annotations

import os
import signal
import threading
import time

import casadi as ca
import pytest

from casadrone.optimise.runner import Interrupted, _signals_interrupt, raise_swallowed_signal


def _solve_until_signalled(solver) -> bool:
    """Solve again and again while a SIGINT is sent; True when the signal landed inside a
    solve (the solve returned normally after it), False when it landed in Python between
    solves (Interrupted raised at once: nothing swallowed, try again)."""
    timer = threading.Timer(0.05, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    try:
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            solver(x0=0, lbg=0, ubg=50)  # the handler's exception dies inside CasADi
            if timer.finished.is_set():
                return True
        raise AssertionError("no SIGINT within 10 s")
    except Interrupted:
        return False
    finally:
        timer.join()


def test_a_sigint_inside_a_casadi_solve_is_raised_after_it():
    x = ca.MX.sym("x", 200)
    solver = ca.nlpsol("s", "ipopt", {"x": x, "f": ca.sumsqr(x - 1) + ca.sum1(ca.sin(x) ** 4),
                                      "g": ca.sum1(x ** 2)},
                       {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes",
                        "ipopt.tol": 1e-14, "ipopt.max_iter": 3000})
    before = signal.getsignal(signal.SIGINT)  # whatever the process had (an earlier test's)
    for _ in range(5):
        with _signals_interrupt():
            if not _solve_until_signalled(solver):
                continue
            with pytest.raises(Interrupted) as info:
                raise_swallowed_signal()
            break
    else:
        pytest.fail("the signal never landed inside a solve: nothing was tested")
    assert info.value.signum == signal.SIGINT
    assert signal.getsignal(signal.SIGINT) == before  # outside the block the old one is back


def test_a_signal_swallowed_in_an_outer_block_survives_the_inner_one():
    """A run's setup and its generation loop are nested blocks: a signal swallowed in the setup
    (its solves) must still be raised by the loop's check, not reset when the loop's block opens
    (the handler is called as CasADi calls it, its exception dropped)."""
    with _signals_interrupt():
        try:
            signal.getsignal(signal.SIGINT)(signal.SIGINT, None)
        except Interrupted:
            pass  # what CasADi does with it
        with _signals_interrupt(), pytest.raises(Interrupted):
            raise_swallowed_signal()
