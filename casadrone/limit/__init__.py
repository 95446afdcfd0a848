"""The limit lap: the physically fastest lap of an airframe, a minimum-time optimal-control problem.

- :mod:`casadrone.limit.nlp` builds the NLP once per track layout (the airframe is a parameter);
- :mod:`casadrone.targets` is the registry of target kinds (waypoint balls, gate openings; below
  the configuration, whose track schema reads it), :mod:`casadrone.limit.gates` packs a track's
  targets into the NLP's parameter;
- :mod:`casadrone.limit.attitude` is the quaternion model (no attitude singularity);
- :mod:`casadrone.limit.check` analyses a solution (re-simulation, sensitivities);
  :mod:`casadrone.limit.sensitivity` tables the slopes per 1 % of Table 1 with their
  uncertainty over the verified optima;
- :mod:`casadrone.limit.search` holds the command's searches (the fast path, ``--certify``);
- :mod:`casadrone.limit.result`: the options and the :class:`~casadrone.limit.result.LimitLap`;
- the steps of :func:`casadrone.limit.lap.limit_lap`, each a module of pure functions:
  :mod:`~casadrone.limit.problem` (track → targets, refusals, start state, bounds),
  :mod:`~casadrone.limit.guesses` (initial guesses), :mod:`~casadrone.limit.pointmass` (the
  point-mass reference), :mod:`~casadrone.limit.starts` (the prepared problem and one solve per
  start), :mod:`~casadrone.limit.choose` (re-simulation check, best start, certainty) and
  :mod:`~casadrone.limit.lap` (the result and its sensitivities).
"""
