"""The measured reference table (``configs/references/``): the paper's Table 4, per airframe and
interval, that :mod:`casadrone.benchmark` puts beside its simulated laps."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import Field

from casadrone.config.io import CONFIG_DIR, Schema, load, resolve_config

DEFAULT_REFERENCE = CONFIG_DIR / "references" / "paper-table4.yaml"


class MeasuredAirframe(Schema):
    """One airframe's measured per-interval values (interval j = the flight to waypoint j)."""

    airframe: str = Field(description="the casadrone airframe config the row refers to")
    split_times_s: list[float] = Field(min_length=1, description="time at each waypoint (s)")
    effort_v: list[float] = Field(min_length=1, description="signed controller effort (V)")
    pair_thrust_max_n: list[float] = Field(min_length=1, description="opposing-pair max (N)")
    pair_thrust_min_n: list[float] = Field(min_length=1, description="opposing-pair min (N)")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        found: list[tuple[str, str]] = []
        keys = ("split_times_s", "effort_v", "pair_thrust_max_n", "pair_thrust_min_n")
        lengths = {k: len(v[k]) for k in keys if k in v}
        n = lengths.get("split_times_s")
        for k, m in lengths.items():
            if n is not None and m != n:
                found.append((k, f"expected {n} values (one per waypoint, like split_times_s), "
                              f"got {m}"))
        s = v.get("split_times_s")
        if s is not None and any(b < a for a, b in zip(s, s[1:], strict=False)):
            found.append(("split_times_s", "split times must not decrease (they are cumulative)"))
        hi, lo = v.get("pair_thrust_max_n"), v.get("pair_thrust_min_n")
        if hi is not None and lo is not None and len(hi) == len(lo):
            bad = [j + 1 for j, (a, b) in enumerate(zip(hi, lo, strict=True)) if b > a]
            if bad:
                found.append(("pair_thrust_min_n", f"above pair_thrust_max_n at interval(s) {bad}"))
        return found


class Table4Reference(Schema):
    """Measured per-interval benchmark values (paper Table 4), keyed by airframe name."""

    name: str = Field(description="name of the reference set")
    source: str = Field("", description="where the values come from (paper, table, page)")
    airframes: dict[str, MeasuredAirframe] = Field(
        min_length=1,
        description="measured values per airframe name (SY250, HS200, ...)",
    )

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        rows = v.get("airframes") or {}
        counts = {len(r.split_times_s) for r in rows.values() if isinstance(r, MeasuredAirframe)}
        if len(counts) > 1:
            return [("airframes", f"every airframe needs the same number of intervals, got "
                     f"{sorted(counts)}")]
        return []


def load_reference(path: str | Path | None = None) -> Table4Reference:
    """Load a measured reference table (default: ``configs/references/paper-table4.yaml``)."""
    return load(Table4Reference, resolve_config(path, "references") if path else DEFAULT_REFERENCE)
