"""The limit lap: the physically fastest lap of an airframe, a minimum-time optimal-control problem.

- :mod:`casadrone.limit.nlp` builds the NLP once per track layout (the airframe is a parameter);
- :mod:`casadrone.limit.check` analyses a solution (re-simulation, sensitivities);
- :mod:`casadrone.limit.attitude` is the quaternion model (no attitude singularity);
- :mod:`casadrone.limit.lap` drives the starts and assembles the
  :class:`~casadrone.limit.lap.LimitLap`.
"""
