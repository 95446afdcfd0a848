"""Co-design: the airframe's θ as decision variables of the limit-lap NLP.

- :mod:`casadrone.codesign.frame`: p(θ), hover thrusts and feasibility rules, for numbers and
  CasADi symbols alike;
- :mod:`casadrone.codesign.nlp`: the co-design NLP built around the limit-lap NLPs;
- :mod:`casadrone.codesign.checks`: what co-design can optimise, and the problem loader
  (the schema: :mod:`casadrone.config.codesign`);
- :mod:`casadrone.codesign.driver`: starts, solve, certificates, fronts.

Light to import (no CasADi): the work is imported when :func:`codesign` is called.
"""

from __future__ import annotations

from typing import Any


def codesign(problem: Any, **kwargs: Any):
    """The fastest frame of ``problem`` (a :class:`~casadrone.config.codesign.
    CodesignProblemConfig`, or a path or shipped name of one) in one NLP: a
    :class:`~casadrone.codesign.driver.CodesignResult`."""
    from casadrone.codesign.design import codesign as run

    return run(problem, **kwargs)
