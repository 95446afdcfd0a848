"""The shipped parts catalogue (``casadrone/data/parts``): the raw rows read from their CSV files,
the propellers' C_T(J), C_P(J) fitted over their whole measured range, and :class:`Catalogue`,
the parts looked up by name.

Files (each row cited; the header of each file says where its figures come from):

* ``propellers.csv``: the raw points (J, rpm, C_T, C_P) of every 4-6 inch propeller of the UIUC
  Propeller Database with wind-tunnel J sweeps; ``propeller-list.csv``: one row per propeller
  (database entry, blades, diameter, pitch, blade chord at 75 % radius, source).
* ``motors.csv``: racing motors of the 2205-2407 class, a basis per figure.
* ``packs.csv``: 4S and 6S LiPo packs of 450-1800 mAh; ``lipo-ocv.csv``: cell open-circuit
  voltage curves against state of charge.
"""

from __future__ import annotations

import csv
import difflib
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from functools import cache
from importlib import resources
from typing import Any

from casadrone.parts.records import (
    BASES,
    KINDS,
    MOTOR_FIGURES,
    PACK_FIGURES,
    MotorPart,
    PackPart,
    Part,
    PropellerPart,
    blade_reynolds,
)
from casadrone.propulsion.data import FIT_MIN_STATIC_RPM
from casadrone.propulsion.propeller import fit_coefficients

INCH_M = 0.0254


def data_file(name: str) -> Any:
    """The package-data file ``casadrone/data/parts/<name>`` (a Traversable)."""
    return resources.files("casadrone") / "data" / "parts" / name


def read_rows(name: str) -> list[dict[str, str]]:
    """The rows of a catalogue CSV as dicts (its ``#`` header lines skipped)."""
    with data_file(name).open(encoding="utf-8") as fh:
        return list(csv.DictReader(line for line in fh if not line.startswith("#")))


# --------------------------------------------------------------------------------------------
# Propellers: raw points and their fit
# --------------------------------------------------------------------------------------------


def propeller_points(name: str, rows: Iterable[dict[str, str]] | None = None
                     ) -> list[tuple[float, float, float, float]]:
    """The raw points (J, rpm, C_T, C_P) of a shipped catalogue propeller, in file order."""
    rows = read_rows("propellers.csv") if rows is None else rows
    return [(float(r["J"]), float(r["rpm"]), float(r["CT"]), float(r["CP"]))
            for r in rows if r["propeller"] == name]


def sweeps(points: list[tuple[float, float, float, float]]) -> dict[float, list[tuple]]:
    """The J sweeps of a propeller's points (J > 0) by their rpm, lowest rpm first."""
    out: dict[float, list[tuple]] = {}
    for p in points:
        if p[0] > 0:
            out.setdefault(p[1], []).append(p)
    return dict(sorted(out.items()))


def catalogue_fit_points(points: list[tuple[float, float, float, float]]) -> list[tuple]:
    """The points a catalogue fit uses: the J sweep at the highest rpm (the nearest the database
    comes to a racing rotor's Reynolds number), over its whole measured range, with the static
    points at ≥ 5000 rpm (:data:`casadrone.propulsion.data.FIT_MIN_STATIC_RPM`, as the shipped
    fit; all static points when none is that fast)."""
    by_rpm = sweeps(points)
    sweep = by_rpm[max(by_rpm)] if by_rpm else []
    static = [p for p in points if p[0] == 0]
    fast = [p for p in static if p[1] >= FIT_MIN_STATIC_RPM]
    return (fast or static) + sweep


def _rms(c: list[float], J: list[float], y: list[float]) -> float:
    return (sum((c[0] + c[1] * j + c[2] * j * j - v) ** 2 for j, v in zip(J, y, strict=True))
            / len(J)) ** 0.5


def fit_propeller(row: dict[str, str], points: list[tuple[float, float, float, float]]
                  ) -> PropellerPart:
    """A :class:`PropellerPart` from its ``propeller-list.csv`` row and its raw points: C_T(J),
    C_P(J) quadratics fitted by least squares (absolute residuals: the sweep's end crosses
    zero thrust) to :func:`catalogue_fit_points`, with their RMS residuals."""
    used = catalogue_fit_points(points)
    J = [p[0] for p in used]
    ct = fit_coefficients(J, [p[2] for p in used], relative=False)
    cp = fit_coefficients(J, [p[3] for p in used], relative=False)
    by_rpm = sweeps(points)
    D = float(row["diameter_in"]) * INCH_M
    chord = float(row["chord_075"]) if row["chord_075"] else None
    low, high = (min(by_rpm), max(by_rpm)) if by_rpm else (None, None)

    def reynolds(rpm: float | None) -> float | None:
        return None if rpm is None or chord is None else blade_reynolds(rpm, D, chord)

    return PropellerPart(
        name=row["name"], diameter_m=D, pitch_m=float(row["pitch_in"]) * INCH_M,
        blades=int(row["blades"]), ct_coefficients=(ct[0], ct[1], ct[2]),
        cp_coefficients=(cp[0], cp[1], cp[2]), j_max_measured=max(J),
        rpm_min=min(p[1] for p in points), rpm_max=max(p[1] for p in points), sweep_rpm=high,
        reynolds_075_min=reynolds(low), reynolds_075_fit=reynolds(high),
        ct_rms=_rms(ct, J, [p[2] for p in used]), cp_rms=_rms(cp, J, [p[3] for p in used]),
        points_fitted=len(used), static_measured=any(p[0] == 0 for p in used), mass_kg=None,
        chord_075=chord, source=row["source"])


def shipped_propellers() -> tuple[PropellerPart, ...]:
    """Every propeller of ``propeller-list.csv``, fitted to its points of ``propellers.csv``."""
    rows = read_rows("propellers.csv")
    grouped: dict[str, list[tuple[float, float, float, float]]] = {}
    for r in rows:
        grouped.setdefault(r["propeller"], []).append(
            (float(r["J"]), float(r["rpm"]), float(r["CT"]), float(r["CP"])))
    return tuple(fit_propeller(row, grouped[row["name"]]) for row in read_rows(
        "propeller-list.csv"))


# --------------------------------------------------------------------------------------------
# Motors and packs
# --------------------------------------------------------------------------------------------


def motor_from_row(row: dict[str, str]) -> MotorPart:
    """A :class:`MotorPart` from a ``motors.csv`` row."""
    return MotorPart(
        name=row["name"], kv_rpm_per_v=float(row["kv_rpm_per_v"]),
        resistance_ohm=float(row["resistance_ohm"]),
        no_load_current_a=float(row["no_load_current_a"]),
        no_load_voltage_v=float(row["no_load_voltage_v"]),
        max_current_a=float(row["max_current_a"]), mass_kg=float(row["mass_kg"]),
        basis={f: _basis(row, f"{f}_basis") for f in MOTOR_FIGURES}, source=row["source"])


def ocv_curves() -> dict[str, tuple[tuple[float, ...], tuple[float, ...]]]:
    """The cell open-circuit voltage curves of ``lipo-ocv.csv``: name → (SoC points, volts)."""
    curves: dict[str, list[tuple[float, float]]] = {}
    for r in read_rows("lipo-ocv.csv"):
        curves.setdefault(r["curve"], []).append((float(r["soc"]), float(r["cell_ocv_v"])))
    return {k: (tuple(s for s, _ in v), tuple(u for _, u in v)) for k, v in curves.items()}


def pack_from_row(row: dict[str, str], curves: dict[str, tuple[tuple[float, ...],
                                                                tuple[float, ...]]]) -> PackPart:
    """A :class:`PackPart` from a ``packs.csv`` row, its OCV from ``curves``."""
    soc, volts = curves[row["ocv"]]
    return PackPart(
        name=row["name"], cells=int(row["cells"]),
        capacity_ah=float(row["capacity_mah"]) / 1000, resistance_ohm=float(row["resistance_ohm"]),
        c_rating=float(row["c_rating"]), mass_kg=float(row["mass_kg"]), ocv_soc=soc, ocv=volts,
        ocv_curve=row["ocv"], basis={f: _basis(row, f"{f}_basis") for f in PACK_FIGURES},
        source=row["source"])


def _basis(row: dict[str, str], key: str) -> str:
    if row[key] not in BASES:
        raise ValueError(f"{row['name']}: {key} {row[key]!r} is not one of {', '.join(BASES)}")
    return row[key]


# --------------------------------------------------------------------------------------------
# The catalogue
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Catalogue:
    """Parts by kind, each name once across kinds: :meth:`get` finds one by its name."""

    propellers: tuple[PropellerPart, ...] = ()
    motors: tuple[MotorPart, ...] = ()
    packs: tuple[PackPart, ...] = ()

    def __post_init__(self) -> None:
        seen: set[str] = set()
        for part in self:
            if part.name in seen:
                raise ValueError(f"two parts of the catalogue are named {part.name!r}")
            seen.add(part.name)

    def __iter__(self) -> Iterator[Part]:
        yield from self.propellers
        yield from self.motors
        yield from self.packs

    def of_kind(self, kind: str) -> tuple[Part, ...]:
        """The parts of one kind (:data:`casadrone.parts.records.KINDS`)."""
        tables: dict[str, tuple[Part, ...]] = {
            "propeller": self.propellers, "motor": self.motors, "pack": self.packs}
        return tables[kind]

    def names(self, kind: str | None = None) -> list[str]:
        """Every part's name (of one kind, when given)."""
        return [p.name for p in (self if kind is None else self.of_kind(kind))]

    def get(self, name: str, kind: str | None = None) -> Part:
        """The part named ``name`` (of ``kind``, when given); KeyError naming the closest
        names otherwise."""
        for part in self if kind is None else self.of_kind(kind):
            if part.name == name:
                return part
        close = difflib.get_close_matches(name, self.names(kind), n=3)
        what = kind or "part"
        raise KeyError(f"no {what} named {name!r} in the catalogue"
                       + (f" (did you mean {', '.join(close)}?)" if close else ""))

    def joined(self, other: Catalogue) -> Catalogue:
        """This catalogue with ``other``'s parts added (a name in both is refused)."""
        return Catalogue(self.propellers + other.propellers, self.motors + other.motors,
                         self.packs + other.packs)

    def sizes(self) -> dict[str, int]:
        """How many parts of each kind."""
        return {k: len(self.of_kind(k)) for k in KINDS}


@cache
def shipped_catalogue() -> Catalogue:
    """The catalogue of ``casadrone/data/parts`` (read and fitted once per process)."""
    curves = ocv_curves()
    return Catalogue(shipped_propellers(), tuple(motor_from_row(r) for r in read_rows(
        "motors.csv")), tuple(pack_from_row(r, curves) for r in read_rows("packs.csv")))
