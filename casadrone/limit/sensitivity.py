"""How far the limit lap's dT/dθ can be trusted: each key's sensitivity at the chosen optimum,
scaled per 1 % of the key's paper Table 1 range, with its uncertainty over the other verified
optima of the same call (docs/concepts/limit-lap.md, "What it returns").

dT/dθ comes from the multipliers of one local optimum (envelope theorem, no re-solve), so it
is the slope of *that* optimum's lap. The limit lap has many local optima a few tenths of a per
cent apart (SY250 on the paper track: 3.8795 s and 3.8800 s gave dT/dλa = −0.074 and +0.135 ms
per mm), and a change of the frame can move the best lap from one to another. So a slope is
reported with the range of the slopes of every verified optimum the call found: its
uncertainty is the largest distance from the chosen optimum's slope to another's, and where
the optima disagree in sign the slope is "not resolved". With one optimum (the command's fast
path) there is nothing to compare: the uncertainty is NaN, and ``--certify`` gives it.

A designer reads a slope as what a move of a few percent of the range does to the best lap, and
the best lap found at a neighbouring frame may come from another of the optima the search
counts as the same answer (within casadrone.limit.choose.CERTAIN_REL of the best: ``certainty``
"agreed"; the caller gives that margin in seconds). A central
difference over ±FD_PERCENT % whose two ends come from optima c and k, δ_k apart, shows
(g_c + g_k)/2 ± δ_k/(2h) instead of g_c: so for each such optimum the uncertainty also
covers |g_k − g_c|/2 + δ_k/(2h) (h = FD_PERCENT % of the range). Measured against central
differences of the ``--certify`` laps at ±2 % (benchmarks/RESULTS-limitlap-sensitivity-fd.md):
HS210's dT/dβ −1.105 ms/% against −0.999 from laps of two grid-round optima, 0.106 apart where
the optima's slopes alone gave ±0.097.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from casadrone.config.airframe import TABLE1_BOUNDS
from casadrone.results import AsDict

#: Share of a key's Table 1 range the scaled slopes are given per (1 %).
PERCENT = 0.01
#: The move (± this many percent of the key's range) whose central difference of the best laps
#: the uncertainty covers (module docstring).
FD_PERCENT = 2.0


def percent_of_range(key: str) -> float:
    """1 % of ``key``'s paper Table 1 range, in the key's unit (mm, deg, kg·m²); NaN for a key
    without a Table 1 range."""
    lo, hi = TABLE1_BOUNDS.get(key, (math.nan, math.nan))
    return PERCENT * (hi - lo)


@dataclass(frozen=True)
class KeySensitivity(AsDict):
    """dT/dθ of one key: at the chosen optimum, and the range over the verified optima.

    ``s_per_unit`` is s per unit of the key (mm, deg, kg·m²), ``s_per_percent`` s per 1 % of
    its Table 1 range; ``uncertainty_*`` the largest distance from it to another verified
    optimum's slope (NaN: one optimum, not estimated); ``low_*``/``high_*`` the slopes' range
    (s per unit); ``resolved`` False where the optima disagree in sign; ``optima`` how many
    verified optima (distinct laps) it was taken over."""

    key: str
    s_per_unit: float
    s_per_percent: float
    uncertainty_s_per_unit: float
    uncertainty_s_per_percent: float
    low_s_per_unit: float
    high_s_per_unit: float
    resolved: bool
    optima: int


def key_sensitivity(key: str, chosen: float, others: Sequence[float],
                    gaps: Sequence[float] | None = None, same_answer_s: float = 0.0
                    ) -> KeySensitivity:
    """The chosen optimum's slope ``chosen`` (s per unit) against the other verified optima's
    (``others``): uncertainty the largest distance to one of them (NaN without any), and, for
    the optima whose lap is at most ``same_answer_s`` from the chosen one (``gaps``: each one's
    lap minus the chosen one, s), |g_k − g_c|/2 + δ_k/(2h) (module docstring); resolved unless
    two slopes have opposite signs (a zero slope agrees with both)."""
    values = np.array([chosen, *others], float)
    unc = float(np.max(np.abs(values[1:] - chosen))) if len(values) > 1 else math.nan
    scale = percent_of_range(key)
    h = FD_PERCENT * scale  # the move, in the key's unit
    for g, gap in zip(others, gaps or (), strict=False):
        if math.isfinite(h) and h > 0 and abs(gap) <= same_answer_s:
            unc = max(unc, abs(g - chosen) / 2 + abs(gap) / (2 * h))
    resolved = not (np.any(values > 0) and np.any(values < 0))
    return KeySensitivity(key, float(chosen), float(chosen * scale), unc, unc * scale,
                          float(values.min()), float(values.max()), bool(resolved), len(values))


def sensitivity_table(chosen: Mapping[str, float], others: Sequence[Mapping[str, float]],
                      gaps: Sequence[float] | None = None, same_answer_s: float = 0.0
                      ) -> tuple[KeySensitivity, ...]:
    """One :class:`KeySensitivity` per key of ``chosen`` (dT/dθ of the chosen optimum, s per
    unit) against the same keys of the other verified optima (their laps ``gaps`` s slower;
    those at most ``same_answer_s`` slower are the same answer)."""
    table = []
    for k, v in chosen.items():
        pairs = [(o[k], gap) for o, gap in zip(others, gaps or [0.0] * len(others),
                                              strict=True) if k in o]
        table.append(key_sensitivity(k, v, [g for g, _ in pairs],
                                     [gap for _, gap in pairs] if gaps is not None else None,
                                     same_answer_s))
    return tuple(table)
