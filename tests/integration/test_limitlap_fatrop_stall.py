"""fatrop's endless inertia-correction loop, met on a real limit lap, ends in bounded time.

SY250 on the paper track with 10 intervals per leg, from its point-mass start: fatrop 1.1.8
(casadi 3.8.2) enters the loop within its first iterations and never returns; unguarded, the
same solve ran past 400 s of wall time without an answer (``casadrone limit-lap SY250 --solver
fatrop --intervals 10``; casadrone.limit.watchdog). Guarded with a 3 s limit it must come back
within a minute, either converged or failed with the guard's status, and the limit lap then
falls back to IPOPT. About 10 s. Should the guard ever fail to end the solve, SIGALRM's default
action ends the test process after 300 s: a loud failure, not a hung suite."""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest

from casadrone.airframe import build_airframe
from casadrone.config.airframe import load_airframe
from casadrone.config.io import load
from casadrone.config.track import TrackConfig
from casadrone.evaluate import DEFAULT_TRACK
from casadrone.limit import lap as limit
from casadrone.limit.nlp import _solve_fatrop
from casadrone.limit.starts import prepare


@pytest.mark.skipif(not hasattr(os, "fork"), reason="the guard needs os.fork")
def test_fatrop_stall_on_a_coarse_grid_returns():
    cfg = load_airframe("SY250")
    frame = build_airframe(cfg)
    options = limit.LimitLapOptions(intervals=10)
    pb = prepare(frame, load(TrackConfig, DEFAULT_TRACK), options,
                 limit.frame_clearance_m(frame, cfg.prop_diameter_mm / 1000))
    previous = signal.signal(signal.SIGALRM, signal.SIG_DFL)
    signal.alarm(300)
    try:
        t0 = time.monotonic()
        sol = _solve_fatrop(pb.full, pb.lifted, pb.P, *pb.box, None, *pb.rows, stall_s=3.0)
        took = time.monotonic() - t0
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    assert took < 60.0, took
    if not sol.success:  # what fatrop 1.1.8 does here (observed: the guard's status after ~4 s)
        assert sol.return_status.startswith("fatrop stalled"), sol.return_status
        assert np.isnan(sol.objective) and sol.iterations == 0
