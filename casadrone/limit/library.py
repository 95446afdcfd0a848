"""The shipped laps: the best limit lap known of a reference airframe on each shipped track,
kept as package data (``casadrone/data/laps/*.npz``) so that the fast path starts every frame
from it instead of searching cold (docs/concepts/limit-lap.md, "Starts and checks").

Why: the limit lap has many local optima a few tenths of a percent apart (the switching of
bang-bang rotor commands, which side of a target a leg clips), and which one a cold start
reaches depends on the grid, the start and even the last bits of the derivatives. Finding the
best costs the certify search (every cold start and grid rounds, minutes of CPU); a lap of a
frame near the reference, started from the reference's best lap (primal-dual where the layout
is the same, resampled otherwise), stays in that basin by continuation and converges in tens of
iterations. Measured (benchmarks/RESULTS-limitlap-fastpath.md): HS210 from SY250's paper-track
lap reaches 3.8312 s (its best known 3.8307 s) in 2.3 s of CPU; over 50 random Table 1 frames
the lap from SY250's shipped lap is within a few tenths of a percent of the best of four cold
starts, and often below it.

A shipped lap is used only for the track it was solved on (the SHA-256 of the track's
validated settings, so an edited copy of a shipped track is another track) and for frames of
the same propulsion kind (the rotor states mean the same); anything else finds none, and the
fast path falls back to its cold starts. Each file records the command that wrote it
(:mod:`casadrone.limit.ship`), the lap, the frame, the package revision and the date.

Write or refresh one with ``python -m casadrone.limit.ship AIRFRAME [--track NAME]``: the
``--certify`` search of that airframe on that track (default: the paper track), saved as
``<track>--<airframe>.npz``.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
from dataclasses import asdict, dataclass
from functools import cache
from pathlib import Path

import numpy as np

from casadrone import __version__
from casadrone.config.track import TrackConfig
from casadrone.limit.nlp import Layout, NlpPoint
from casadrone.limit.result import LimitLap

#: Where the shipped laps live (package data).
LIBRARY_DIR = Path(__file__).resolve().parent.parent / "data" / "laps"
#: Arrays of a lap file besides its JSON metadata ("meta").
ARRAYS = ("w", "lam_x", "lam_g", "lam_p", "t", "x", "u", "leg_times_s")


@dataclass(frozen=True)
class ShippedLap:
    """One shipped lap: the lap (enough to start another from it) and where it came from."""

    name: str  # the airframe it was solved for (the start's name: ``library-<name>``)
    track_sha256: str
    propulsion: str
    lap: LimitLap
    meta: dict


def track_key(track: TrackConfig) -> str:
    """The identity of a track: SHA-256 of its validated settings (field order fixed by the
    schema), so the same track from any file matches and an edited one does not."""
    return hashlib.sha256(track.model_dump_json().encode()).hexdigest()


def _layout(d: dict) -> Layout:
    return Layout(**{**d, "kinds": tuple(d["kinds"])})


def read(path: Path) -> ShippedLap:
    """A lap file as written by :func:`write` (ValueError naming the file when it is not one)."""
    with np.load(path, allow_pickle=False) as f:
        missing = [k for k in (*ARRAYS, "meta") if k not in f.files]
        if missing:
            raise ValueError(f"{path}: not a shipped lap (missing {', '.join(missing)})")
        a = {k: np.asarray(f[k], float) for k in ARRAYS}
        meta = json.loads(str(f["meta"]))
    lap = LimitLap(status="completed", reason="", lap_time_s=float(meta["lap_time_s"]),
                   leg_times_s=a["leg_times_s"], t=a["t"], x=a["x"], u=a["u"],
                   attitude=meta["attitude"], layout=_layout(meta["layout"]),
                   solution=NlpPoint(a["w"], a["lam_x"], a["lam_g"], a["lam_p"]),
                   propulsion=meta["propulsion"], start=meta["start"])
    return ShippedLap(meta["airframe"], meta["track_sha256"], meta["propulsion"], lap, meta)


def write(path: Path, lap: LimitLap, airframe: str, track: TrackConfig, track_name: str,
          command: str) -> Path:
    """Save a completed lap with its provenance (the layout, the lap, the command, the
    package's version and the date)."""
    if not lap.completed or lap.solution is None or lap.layout is None:
        raise ValueError(f"only a completed lap with its solution is shipped ({lap.reason})")
    meta = {"airframe": airframe, "track": track_name, "track_sha256": track_key(track),
            "propulsion": lap.propulsion, "attitude": lap.attitude,
            "layout": asdict(lap.layout), "lap_time_s": lap.lap_time_s, "start": lap.start,
            "certainty": lap.certainty, "ending": lap.ending, "command": command,
            "casadrone": __version__, "date": _dt.date.today().isoformat()}
    sol = lap.solution
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as f:
        np.savez_compressed(f, meta=np.array(json.dumps(meta)), w=sol.w, lam_x=sol.lam_x,
                            lam_g=sol.lam_g, lam_p=sol.lam_p, t=lap.t, x=lap.x, u=lap.u,
                            leg_times_s=lap.leg_times_s)
    return path


@cache
def _shipped(directory: Path) -> tuple[ShippedLap, ...]:
    return tuple(read(p) for p in sorted(directory.glob("*.npz")))


def shipped_laps(track: TrackConfig, propulsion: str, directory: Path = LIBRARY_DIR
                 ) -> tuple[ShippedLap, ...]:
    """The shipped laps of ``track`` for frames of kind ``propulsion`` (read once per
    process), fastest first."""
    key = track_key(track)
    found = [s for s in _shipped(directory) if s.track_sha256 == key
             and s.propulsion == propulsion]
    return tuple(sorted(found, key=lambda s: s.lap.lap_time_s))


def usable(shipped: ShippedLap, layout: Layout, attitude: str) -> str | None:
    """How a shipped lap starts a problem of ``layout`` and ``attitude``: "warm" (primal-dual,
    the same NLP), "resampled" (the same legs and transcription, another grid or attitude) or
    None (other legs: it cannot)."""
    lay = shipped.lap.layout
    if lay is None or lay.kinds != layout.kinds or lay.method != layout.method:
        return None
    return "warm" if lay == layout and shipped.lap.attitude == attitude else "resampled"
