"""The run directory: what a run leaves on disk and reads back to report, compare, export or resume
it (docs/architecture.md#runs).

- :mod:`casadrone.rundir.store`: the directory itself (:class:`~casadrone.rundir.store.RunStore`:
  the resolved problem, the manifest, ``history.sqlite``, the front), its locks and refusals;
- :mod:`casadrone.rundir.writer`: the coordinator's writer of each generation;
- :mod:`casadrone.rundir.checkpoint`: the checkpoints a run resumes from;
- :mod:`casadrone.rundir.timings`: ``timings.csv``;
- :mod:`casadrone.rundir.plugins`: the problem's plugins, imported once per process.

The optimiser (:mod:`casadrone.optimise`), co-design (:mod:`casadrone.codesign`) and the outputs
(comparison, report, export) all read and write runs through it; it imports none of them.
"""
