"""The ε row on effort, lifted into its running sum (casadrone.codesign.nlp).

Oracles: the running sum recomputed with numpy from the limit lap's unpacked nodes (thrusts and
interval lengths), independently of the NLP's symbolic effort; and the constraint Jacobian's
forward colouring, which one dense row over every interval would multiply (124 colours against
30 on this track before the lifting, benchmarks/RESULTS-codesign.md).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from casadrone.codesign.checks import load_codesign_problem
from casadrone.codesign.driver import constrained, initial_vector, prepare, start_points
from casadrone.indices import EFFORT_SMOOTHING_N

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def preps():
    cfg = load_codesign_problem(str(ROOT / "tests/data/codesign/short-front.yaml"), [])
    prep = prepare(cfg)
    (_, theta), *_ = start_points(prep)
    z0 = initial_vector(prep, theta)
    assert z0 is not None
    return prep, constrained(prep, ("effort",)), z0


def test_running_sum_equals_the_effort_recomputed_from_the_nodes(preps):
    prep, eps, z0 = preps
    z = eps.nlp.full(z0)
    assert len(z) == eps.nlp.nw == len(z0) + eps.nlp.n_lift
    part = prep.nlp.parts[0]
    legs, X, _ = part.nlp.unpack(prep.nlp.split(z0)[0][0])
    n = part.nlp.layout.intervals
    h = np.repeat(legs / n, n)  # each interval's length (s)
    thrusts = X[:-1, part.nlp.model.rotor]  # each interval's start node (N)
    power = np.sum((thrusts ** 2 + EFFORT_SMOOTHING_N ** 2) ** 0.75, axis=1)
    np.testing.assert_allclose(z[len(z0):], np.cumsum(power * h), rtol=1e-12)
    # the lifted rows hold at that point: E_k − E_{k−1} − q_k = 0 (the last rows of g)
    g = np.asarray(eps.nlp.cold.get_function("nlp_g")(z, np.array([1e3]))).ravel()
    np.testing.assert_allclose(g[-eps.nlp.n_lift:], 0.0, atol=1e-10)
    assert np.isclose(g[-eps.nlp.n_lift - 1], z[-1] - 1e3)  # the ε row: E_M − ε


def test_effort_row_keeps_the_jacobian_colouring(preps):
    prep, eps, _ = preps
    free = prep.nlp.cold.get_function("nlp_jac_g").sparsity_out(1).uni_coloring().size2()
    lifted = eps.nlp.cold.get_function("nlp_jac_g").sparsity_out(1).uni_coloring().size2()
    assert lifted <= free + 2  # a dense row would add one colour per interval's five nonzeros
