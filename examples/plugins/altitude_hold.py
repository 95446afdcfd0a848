"""A custom index, registered when this module is imported: RMS altitude error on the race legs.

Problems load it with ``plugins: [examples/plugins/altitude_hold.py]`` so that every worker process
(processes or Dask backends) registers it too.
"""

import numpy as np

from casadrone.indices import INDICES, lap_mask, register_index


def altitude_rms(traj) -> float:
    """RMS of (z − z_ref) over the lap after the climb (m)."""
    first = traj.first_timed_segment
    mask = lap_mask(traj) & (traj.segment > first)
    dz = traj.x[mask, 2] - traj.p_ref[mask, 2]
    return float(np.sqrt(np.mean(dz**2)))


if "Jz" not in INDICES:
    register_index("Jz", altitude_rms, unit="m", sense="min",
                   description="RMS altitude error on the race legs")
