"""``python -m casadrone.limit.ship AIRFRAME [--track NAME] [--out DIR]``: the ``--certify``
limit lap of a shipped airframe on a shipped track (default: the paper's), written as a shipped
lap (:mod:`casadrone.limit.library`) for the fast path to start from. The library's own laps
never start from the library: the certificate's cold starts and grid rounds only."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from casadrone.airframe import build_airframe
from casadrone.config.airframe import load_airframe
from casadrone.config.io import load, resolve_config
from casadrone.config.limitlap import LimitLapConfig
from casadrone.config.track import DEFAULT_TRACK, TrackConfig
from casadrone.limit.lap import design_limit_lap
from casadrone.limit.library import LIBRARY_DIR, write
from casadrone.limit.search import lap_options


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("airframe")
    ap.add_argument("--track", default=None, help="a shipped track (default: the paper's)")
    ap.add_argument("--out", type=Path, default=LIBRARY_DIR)
    args = ap.parse_args(argv)
    track_path = DEFAULT_TRACK if args.track is None else resolve_config(args.track, "tracks")
    track = load(TrackConfig, track_path)
    cfg = load_airframe(args.airframe)
    options = lap_options(LimitLapConfig(search="certify"), periodic=track.end == "periodic")
    options = replace(options, starts=tuple(s for s in options.starts if s != "library"))
    lap = design_limit_lap(cfg, track, options, frame=build_airframe(cfg))
    if not lap.completed:
        print(f"{args.airframe}: no lap to ship ({lap.reason})", file=sys.stderr)
        return 1
    command = " ".join(["python -m casadrone.limit.ship", args.airframe]
                       + (["--track", args.track] if args.track else []))
    path = write(args.out / f"{track_path.stem}--{args.airframe}.npz", lap, args.airframe,
                 track, track_path.stem, command)
    print(f"{path}: {lap.lap_time_s:.6f} s from {lap.start} ({lap.certainty}), "
          f"{lap.cpu_time_s:.0f} s CPU")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
