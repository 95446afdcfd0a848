"""No negative zero in printed tables (casadrone.numtext.fixed)."""

from __future__ import annotations

import math

import pytest

from casadrone.numtext import fixed


@pytest.mark.parametrize(("value", "spec", "shown"), [
    (-3e-7, ".4f", "0.0000"),          # rounds to zero: no sign
    (-0.0, ".4f", "0.0000"),
    (-3e-7, ">10.4f", "    0.0000"),   # the width kept
    (-3e-7, "<8.3f", "0.000   "),
    (-3e-7, "+.3f", "+0.000"),         # an explicit sign is the spec's, kept for zero
    (-0.0, ".4g", "0"),
    (-0.00049, ".3f", "0.000"),
    (-0.0005, ".3f", "-0.001"),         # a value that shows a digit keeps its sign
    (-1e-12, ".3g", "-1e-12"),
    (-2.5, "9.4f", "  -2.5000"),
    (1e-7, ".4f", "0.0000"),
])
def test_fixed(value, spec, shown):
    # the expected texts are typed in by hand: Python's format of the value, less the sign
    assert fixed(value, spec) == shown


def test_non_finite_values_as_python_prints_them():
    assert fixed(math.nan, ".3f") == "nan"
    assert fixed(-math.inf, ".3f") == "-inf"
