"""Numbers as printed text: one rule for every table casadrone prints (terminal and report).

A value that rounds to zero at the printed precision is printed without a sign: ``-0.0000``
reads as a negative number, although it says only that the value is smaller than the last
digit (a roll effort of -3e-7 V in a level interval). Light on purpose: no numpy, no CasADi.
"""

from __future__ import annotations

import math

#: The digits that make a printed mantissa non-zero.
_NONZERO = frozenset("123456789")


def fixed(value: float, spec: str) -> str:
    """``format(value, spec)`` (any format spec: width, alignment, sign, precision), except that
    a value shown as zero is shown as ``format(0.0, spec)``: no negative zero. Non-finite values
    are formatted as Python does (``nan``, ``inf``)."""
    text = format(value, spec)
    if not math.isfinite(value) or "-" not in text:
        return text
    mantissa = text.lower().split("e")[0]
    return text if _NONZERO & set(mantissa) else format(0.0, spec)
