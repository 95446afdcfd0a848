"""The whole build: propeller, motor and pack chosen from the catalogue together with the frame's
geometry, for a race of N laps (``casadrone build``).

- :mod:`casadrone.build.combos`: the combinations, each as an airframe, and the ones refused
  before any solve;
- :mod:`casadrone.build.bound`: the point-mass bound of a combination's lap;
- :mod:`casadrone.build.dominance`: the frame of a geometry box that dominates the others, raced
  instead of a co-design;
- :mod:`casadrone.build.solve`: one combination co-designed and raced;
- :mod:`casadrone.build.search`: branch and bound over the combinations, side by side on a
  process pool or a Dask cluster, and the ranking.

The schema is :mod:`casadrone.config.build`.
"""
