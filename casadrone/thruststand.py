"""A `propulsion:` section fitted from a thrust-stand log (``casadrone fit-propulsion``).

The log is a CSV as the common stands' software writes it (Tyto Robotics / RCbenchmark
Series 1520/1580/1585 and their clones): one row per sample, one column per sensor, the unit in
the header (``Thrust (kgf)``, ``Torque (N·m)``, ``Motor Optical Speed (RPM)`` or ``(rad/s)`` …).
The unit is read from the header and converted to SI; a column in a unit casadrone does not know
is refused, never guessed. What a real log holds besides, and how it is read:

- **ESC signal without a unit: DShot.** A log of a PWM-driven ESC carries ``ESC signal (µs)``; the
  published RCbenchmark logs of bhabas/sar_simulation (``Motor_SO_V5``, MIT licence), recorded
  with ``protocol = "dshot600"`` in their test script, carry ``ESC signal`` with no unit and values
  0-2047 — what Tyto's software writes for DShot, as these logs show. Such a column is read as
  DShot command values, whose throttle range is 48-2047 (0 disarms, 1-47 are commands:
  ``DSHOT_MIN_THROTTLE``/``DSHOT_MAX_THROTTLE`` of Betaflight's and INAV's DShot drivers); the
  duty range then defaults to 48-2047 instead of PWM's 1000-2000 µs (a range given by the user
  is kept). A column whose unit is written but unknown is still refused.
- **Blank cells of a time series.** A stand samples its load cells and its power sensor
  asynchronously: a time series leaves thrust or torque blank in the rows where that sensor gave
  no new sample (alternate rows in the published 100 Hz log above). A blank cell in the thrust,
  torque, voltage or current column is a missing sample (NaN, skipped by every mean); a column
  left without any sample, and any text that is not a number, is refused with its row.
- **Comment rows.** A row whose first cell starts with ``#`` is a comment (the published logs
  above carry their author's fit results so).
- **Refused, never guessed.** Two columns of one quantity (``Thrust (kgf)`` beside
  ``Thrust (N)``), a cell beyond any stand's range (:data:`MAX_MAGNITUDE`), a record the csv
  module cannot read (a quote left open), a log over :data:`MAX_LOG_BYTES`; each with its row or
  columns. The log is read a row at a time into float arrays: memory stays a few times its size.

What is fitted, and from which part of the log:

- **Steady points.** A *plateau* is a run of rows with the same ESC signal lasting at least
  ``min_plateau_s``; its steady value is the mean of its last ``settled_fraction`` (the first part
  holds the step response). A log with no plateau whose rows are at least ``min_plateau_s`` apart
  (median interval) is a log of *averaged rows*: the stands' "discrete steps" script settles at
  each ESC signal and writes one row, the average of many samples (``samplesAvg`` in Tyto's
  ``Motor_Step_Test.js``); each row is then a steady point (:func:`steady_points`; the fit reports
  which of the two it used, and fits no step response from averaged rows). A steady point missing
  a quantity (a blank cell, or a plateau whose settled part has no sample of it) is not used.
  From the steady points:

  - static propeller coefficients, by least squares through the origin of the momentum-theory
    scalings ``T = C_T0 ρ n² D⁴`` and ``P = 2π n Q = C_P0 ρ n³ D⁵`` (n in rev/s; the coefficient
    definitions of the UIUC propeller database, Brandt & Selig 2011, AIAA 2011-1255);
  - the DC motor of Drela's first-order model (M. Drela, "First-Order DC Electric Motor Model",
    MIT 16.50 notes, 2007): terminal voltage ``V_m = ω / K_v + I_m R`` (a linear regression of
    V_m on ω and I_m gives K_v and R) and shaft torque ``Q = (I_m − I_0) / K_v`` (I_0 from the
    mean of ``I_m − K_v Q``). The motor's voltage and current are not measured: the ESC is taken
    as a lossless buck converter, ``V_m = d V_bus`` and ``I_m = I_bus / d``, with the duty d the
    ESC signal's fraction of its range ``[esc_min_us, esc_max_us]`` (the throttle mapping of
    BLHeli-family ESCs without thrust linearisation; 1000-2000 µs for PWM, 48-2047 for DShot);
  - the battery's internal resistance and open-circuit voltage, ``V_bus = V_oc − R_int I_bus``
    (linear regression over the steady points).

- **Step tests.** At each change of the ESC signal the rotor speed's response is fitted with a
  first-order step ``ω(t) = ω_∞ + (ω_0 − ω_∞) e^(−(t − t_0)/τ)`` (scipy least squares); the
  motor time constant is the median over the steps. The DC motor's rotor inertia follows from
  each τ by linearising ``J_r ω̇ = Q_m(ω) − Q_p(ω)`` at the step's end point:
  ``J_r = τ (∂Q_p/∂ω − ∂Q_m/∂ω) = τ (2 Q_p/ω + 1 / (K_v² (R + R_int d²)))`` (the propeller's
  torque grows with ω²; the motor's falls with the back-EMF through the winding and the battery
  seen through the ESC); the median over the steps. The linearisation holds for small steps:
  a stand's step test of 50 µs increments is what to log. A step whose response the sampling
  cannot resolve (fewer than ``MIN_STEP_SAMPLES`` samples within three time constants) is not
  used; with no resolved step the time constant and inertia are reported as not measured, never
  invented.

**Parts, each alone.** The propeller, the motor and the battery (:data:`PARTS`) are fitted and
judged apart: a part whose values fall outside :data:`PHYSICAL`, or that the airframe schema
refuses, is reported refused with the reason and the others are kept. The motor needs the
lossless-ESC assumption above, which DShot ESCs seldom meet (the published DShot logs give a
negative no-load current or K_V); the propeller needs only thrust, torque and speed, and fits
them (their authors' own k_f, k_q within 1 %). A section then holds the parts fitted only.

The shape of C_T and C_P against the advance ratio J cannot be measured on a static stand: the
section carries the static coefficients as ``ct_coefficients: [C_T0]`` and
``cp_coefficients: [C_P0]`` unless a propeller of the package's data is named as the shape
(:func:`shaped_coefficients`), whose polynomials are then scaled to the fitted static values.
"""

from __future__ import annotations

import codecs
import csv
import math
import re
import stat
import warnings
from array import array
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from casadrone.config.io import error_pairs
from casadrone.config.propulsion import (
    BatteryConfig,
    MotorConfig,
    PropellerConfig,
    PropulsionConfig,
    data_advance_ratio,
)
from casadrone.propulsion import airframe_problems, fit_coefficients, fit_points, propeller_data

#: Standard gravity (m/s²): the stands' kgf and gf are kilogram- and gram-force.
G0 = 9.80665
#: International Standard Atmosphere sea-level air density (kg/m³): the default of ``air_density``.
RHO_ISA = 1.225
#: Fewest samples inside three time constants for a step response to count.
MIN_STEP_SAMPLES = 5
#: Largest log read (bytes). Real logs are a few MB to tens of MB (14 minutes at 10 Hz: ~8 400
#: rows, ~1 MB; a Tyto time series at 110 Hz: ~1.5 MB a minute). Read whole, as before, a log
#: cost ~16-19x its size in memory (21 MB: 337 MB above the imports' ~107 MB; 69 MB: 1.29 GB);
#: read a row at a time into float arrays it costs 1.2x (that 21 MB log: 25 MB above) and at
#: worst 3.8x (66 MB of one-character cells: 250 MB above, 358 MB peak RSS): 64 MB keeps the
#: peak well under 1 GB.
MAX_LOG_BYTES = 64 * 1024 * 1024
#: Longest line read (characters): a stand's row is a few hundred; a longer one is not a log row
#: (and is not read whole into memory).
MAX_LINE_CHARS = 1 << 20
#: Most steady points fitted: a stand's step test holds tens to hundreds, each held ≥ 0.5 s (20 000
#: are ≥ 2.8 hours of steps); each costs ~1 kB in the fit (a log of 26 MB, one point per row,
#: peaked at 860 MB), so more are refused before they are built.
MAX_STEADY_POINTS = 20_000
#: Largest magnitude of each quantity in SI (s, µs or DShot value, N, N·m, V, A, rad/s), beyond
#: any thrust stand (a 10-tonne-force load cell, 10 kV, ~10 million rpm): a cell beyond is refused
#: naming its row, before it can overflow a fit.
MAX_MAGNITUDE: dict[str, tuple[float, str]] = {
    "time": (1e10, "s"), "esc": (1e4, ""), "thrust": (1e5, "N"), "torque": (1e4, "N·m"),
    "voltage": (1e4, "V"), "current": (1e4, "A"), "optical_rpm": (1e6, "rad/s"),
    "electrical_rpm": (1e7, "rad/s"),
}
#: Ranges of the fit's options: propeller diameter (m), air density (kg/m³), ESC signal (µs or
#: DShot value, as :data:`MAX_MAGNITUDE`).
DIAMETER_RANGE_M = (0.02, 2.0)
AIR_DENSITY_RANGE = (0.3, 1.5)
ESC_SIGNAL_RANGE = (0.0, MAX_MAGNITUDE["esc"][0])
#: Default duty range ``(zero, full)`` of the ESC signal per protocol: PWM pulse width (µs) of the
#: BLHeli-family ESCs, DShot throttle commands (48-2047, module docstring).
ESC_RANGES: dict[str, tuple[float, float]] = {"pwm": (1000.0, 2000.0), "dshot": (48.0, 2047.0)}
#: Where the steady points came from (module docstring): held plateaus of a time series, or one
#: averaged row per step.
SteadySource = Literal["plateaus", "averaged rows"]
#: The parts a log fits, each alone (module docstring): a part whose fit is not physical is
#: refused and the others are kept; ``--part`` of ``casadrone fit-propulsion`` chooses among them.
PARTS: tuple[str, ...] = ("propeller", "motor", "battery")
PartStatus = Literal["fitted", "refused", "not fitted"]
#: The :class:`PropulsionFit` values of each part.
PART_VALUES: dict[str, tuple[str, ...]] = {
    "propeller": ("ct0", "cp0"),
    "motor": ("kv_rpm_per_v", "resistance_ohm", "no_load_current_a"),
    "battery": ("open_circuit_voltage_v", "internal_resistance_ohm"),
}


class LogError(ValueError):
    """A log that cannot be fitted: the message names the file and the column or row."""


# ------------------------------------------------------------------------------------------------
# Columns: quantity, header pattern, units
# ------------------------------------------------------------------------------------------------

#: Factor to SI of each unit a stand writes, per quantity (the ESC signal to µs). The µ of "µs"
#: is also accepted as "us" and as the mojibake some exports carry (:data:`_MOJIBAKE_US`).
UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3},
    "esc": {"µs": 1.0, "us": 1.0, "ms": 1e3},
    "thrust": {"n": 1.0, "kgf": G0, "kg": G0, "gf": G0 * 1e-3, "g": G0 * 1e-3,
               "lbf": 4.4482216152605},
    "torque": {"n·m": 1.0, "n-m": 1.0, "nm": 1.0, "n.m": 1.0, "n*m": 1.0, "n·mm": 1e-3,
               "nmm": 1e-3, "kgf·cm": G0 * 1e-2},
    "voltage": {"v": 1.0},
    "current": {"a": 1.0},
    "optical_rpm": {"rpm": 2 * math.pi / 60, "rad/s": 1.0},
    "electrical_rpm": {"rpm": 2 * math.pi / 60, "rad/s": 1.0},
}
#: Header name (before the unit) of each quantity, lower case.
NAMES: dict[str, tuple[str, ...]] = {
    "time": ("time",),
    "esc": ("esc signal", "esc"),
    "thrust": ("thrust",),
    "torque": ("torque",),
    "voltage": ("voltage",),
    "current": ("current",),
    "optical_rpm": ("motor optical speed",),
    "electrical_rpm": ("motor electrical speed",),
}
REQUIRED = ("time", "esc", "thrust", "torque", "voltage", "current")
#: Columns whose blank cells are missing samples of an asynchronous sensor (module docstring).
SPARSE = ("thrust", "torque", "voltage", "current")
_HEADER = re.compile(r"^\s*(?P<name>[^()]*?)\s*\((?P<unit>[^()]*)\)\s*$")


#: "µs" as exports mis-decode it: the µ turned into a short run of non-ASCII characters ("Âµs":
#: UTF-8 read as Latin-1), or the µ and the s into one ("탎": cp1252 read as cp949). Only a
#: non-ASCII run: "ms", "s" or "ns" are other units, never taken for µs.
_MOJIBAKE_US = re.compile(r"[^\x00-\x7f]{1,3}s?")


def _unit_key(quantity: str, unit: str) -> str:
    key = unit.strip().lower().replace(" ", "")
    if quantity == "esc" and key not in UNITS["esc"] and _MOJIBAKE_US.fullmatch(key):
        return "µs"
    return key


@dataclass(frozen=True)
class StandLog:
    """A thrust-stand log in SI units (one entry per sample, in time order).

    Attributes:
        source: the file's name (no directory: results carry no machine path).
        time_s, esc_us, thrust_n, torque_nm, voltage_v, current_a: the samples; thrust, torque,
            voltage and current are NaN where the log's cell is blank. ``esc_us`` is the ESC
            signal as logged: a pulse width (µs) for PWM, a command value for DShot.
        speed_rad_s: rotor (mechanical) speed, from the optical sensor or the electrical speed
            divided by the motor's pole pairs.
        esc_protocol: "pwm" (``ESC signal (µs)``) or "dshot" (``ESC signal`` without a unit).
    """

    source: str
    time_s: np.ndarray
    esc_us: np.ndarray
    thrust_n: np.ndarray
    torque_nm: np.ndarray
    voltage_v: np.ndarray
    current_a: np.ndarray
    speed_rad_s: np.ndarray
    esc_protocol: str = "pwm"


def _quantity(text: str) -> tuple[str, str | None] | None:
    """The quantity a header cell names and its unit as written (None: no unit written), or None
    for a column casadrone does not read."""
    m = _HEADER.match(text)
    if not m:
        return ("esc", None) if text.strip().lower() in NAMES["esc"] else None
    name = m["name"].strip().lower()
    return next(((q, m["unit"]) for q, names in NAMES.items() if name in names), None)


def _columns(header: list[str], source: str) -> tuple[dict[str, tuple[int, float]], str]:
    """quantity → (column index, factor to SI), from the header's names and units; and the ESC
    protocol: "dshot" where the ESC signal's header has no unit (module docstring). Two columns
    of one quantity are refused: which one holds the data is not guessed."""
    found: dict[str, tuple[int, float]] = {}
    protocol = "pwm"
    for j, text in enumerate(header):
        named = _quantity(text)
        if named is None:
            continue
        quantity, written = named
        if quantity in found:
            raise LogError(f"{source}: columns '{header[found[quantity][0]]}' and '{text}' are "
                           f"both {quantity}: keep one (which holds the data is not guessed)")
        if written is None:
            found[quantity] = (j, 1.0)
            protocol = "dshot"
            continue
        unit = _unit_key(quantity, written)
        if unit not in UNITS[quantity]:
            known = ", ".join(UNITS[quantity])
            raise LogError(f"{source}: column '{text}': unit '{written}' not known for "
                           f"{quantity} (known: {known})")
        found[quantity] = (j, UNITS[quantity][unit])
    for quantity in REQUIRED:
        if quantity not in found:
            raise LogError(f"{source}: column missing: {quantity} (e.g. "
                           f"'{NAMES[quantity][0].capitalize()} (unit)'){_separator_hint(header)}")
    return found, protocol


def _separator_hint(header: list[str]) -> str:
    """Why no column was found when the header is UTF-16 read as UTF-8 (NUL bytes between the
    characters) or one cell holding another separator (a semicolon or tab export): said, instead
    of only the first column missing, which reads as a misnamed column."""
    if any("\x00" in cell for cell in header):
        return "; the header holds NUL bytes: a UTF-16 file? save it as UTF-8"
    if len(header) != 1:
        return ""
    cell = header[0]
    for sep, name in ((";", "semicolons"), ("\t", "tabs")):
        if sep in cell:
            return (f"; the header reads as one column separated by {name}: the log must be "
                    "comma-separated")
    return ""


def check_log_file(path: Path) -> None:
    """LogError unless ``path`` is a regular file of at most :data:`MAX_LOG_BYTES` (a folder, a
    FIFO or a device is said to be one, not "not found")."""
    try:
        mode = path.stat()
    except FileNotFoundError:
        raise LogError(f"{path}: file not found") from None
    except OSError as exc:
        raise LogError(f"{path}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(mode.st_mode):
        raise LogError(f"{path}: is a directory, not a log file")
    if not stat.S_ISREG(mode.st_mode):
        raise LogError(f"{path}: not a regular file (a device, FIFO or socket), not a log")
    if mode.st_size > MAX_LOG_BYTES:
        raise LogError(f"{path}: larger than {MAX_LOG_BYTES // 2**20} MB, not a stand log")


def _latin1_fallback(exc: UnicodeError) -> tuple[str, int]:
    """Decode error handler: the bytes that are not UTF-8 read as Latin-1 (see :data:`ENCODING`)."""
    assert isinstance(exc, UnicodeDecodeError)
    return exc.object[exc.start:exc.end].decode("latin-1"), exc.end


#: How a log is decoded: UTF-8 (a BOM skipped), each byte that is not UTF-8 read as Latin-1
#: (Windows exports write "µ" and "·" as the single bytes B5, B7). Byte by byte, not the whole file
#: at once: one stray Latin-1 byte in a UTF-8 log (a comment, an operator's note) used to turn the
#: whole file to Latin-1, its header's "N·m" into "NÂ·m", and the log was refused for a unit.
ENCODING, DECODE_ERRORS = "utf-8-sig", "casadrone-latin-1-fallback"
codecs.register_error(DECODE_ERRORS, _latin1_fallback)


def _lines(fh, source: str) -> Iterator[str]:
    """The file's lines, refusing one longer than :data:`MAX_LINE_CHARS` before reading it all."""
    number = 0
    while line := fh.readline(MAX_LINE_CHARS + 1):
        number += 1
        if len(line) > MAX_LINE_CHARS:
            raise LogError(f"{source}: line {number}: longer than {MAX_LINE_CHARS} characters, "
                           "not a stand log's row")
        yield line


def _records(fh, source: str) -> Iterator[tuple[int, list[str]]]:
    """(row number, cells) of each CSV record, comment rows skipped and not counted (module
    docstring); a record csv cannot read (an unclosed quote swallowing the lines after it, a
    cell over csv's field limit) is refused naming its row."""
    reader = csv.reader(_lines(fh, source))
    number = 0
    while True:
        try:
            row = next(reader)
        except StopIteration:
            return
        except csv.Error as exc:
            raise LogError(f"{source}: row {number + 1}: {exc} (an unclosed quote, or a cell "
                           f"longer than {csv.field_size_limit()} characters)") from None
        if row and row[0].lstrip().startswith("#"):
            continue
        number += 1
        yield number, row


def _shown(cell: str) -> str:
    """A cell as an error message quotes it: at most 40 characters; a cell holding line breaks
    (a quote left open) said to be one."""
    shown = repr(cell if len(cell) <= 40 else cell[:40] + "…")
    return shown + (" (a quote left open runs over the lines after it)" if "\n" in cell else "")


def _value(quantity: str, cell: str, factor: float) -> float:
    """The SI value of one (stripped) cell; ValueError saying why it is none (module
    docstring: a blank sparse or speed cell is a missing sample, NaN)."""
    if not cell:
        if quantity.endswith("rpm") or quantity in SPARSE:
            return math.nan
        raise ValueError(f"not a number: {_shown(cell)}")
    try:
        value = float(cell) * factor
    except ValueError:
        raise ValueError(f"not a number: {_shown(cell)}") from None
    if not math.isfinite(value):
        if quantity.endswith("rpm"):
            return value  # refused by _rotor_speed only in the column used
        raise ValueError(f"not a number: {_shown(cell)}")
    limit, unit = MAX_MAGNITUDE[quantity]
    if abs(value) > limit:
        raise ValueError(f"{_shown(cell)} is beyond any thrust stand's range (at most "
                         f"{limit:g} {unit} in magnitude)".replace("  ", " "))
    return value


def _read_columns(fh, source: str) -> tuple[dict[str, str], dict[str, np.ndarray], str]:
    """Each used column's header and SI values (a row of blank cells skipped), and the ESC
    protocol; read a row at a time into float arrays."""
    records = _records(fh, source)
    # the header is the first record with a cell: blank lines above it are no header
    header = next((row for _, row in records if any(cell.strip() for cell in row)), [])
    cols, protocol = _columns(header, source)
    data = {q: array("d") for q in cols}
    rows = 0
    for i, row in records:
        if not any(cell.strip() for cell in row):
            continue
        rows += 1
        for q, (j, factor) in cols.items():
            try:
                data[q].append(_value(q, row[j].strip() if j < len(row) else "", factor))
            except ValueError as exc:
                raise LogError(f"{source}: row {i}, column '{header[j]}': {exc}") from None
    if not rows:
        raise LogError(f"{source}: no data rows")
    names = {q: header[j] for q, (j, _) in cols.items()}
    return names, {q: np.frombuffer(v, dtype=float) for q, v in data.items()}, protocol


def read_log(path: str | Path, motor_poles: int | None = None) -> StandLog:
    """Read a stand log (units from the header) into SI arrays.

    Rotor speed comes from ``Motor Optical Speed (RPM or rad/s)`` when it holds data, else from
    ``Motor Electrical Speed`` (see :func:`_rotor_speed` for ``motor_poles``, an even number).
    A blank thrust, torque, voltage or current cell is a missing sample (NaN); a column of them
    without any sample, a blank time or ESC signal, a non-numeric value in a used column and a
    value beyond :data:`MAX_MAGNITUDE` are refused with the row number (the row of the file,
    comment rows counted out); so are two columns of one quantity.
    """
    path = Path(path)
    source = path.name
    if motor_poles is not None and (motor_poles < 2 or motor_poles % 2):
        raise LogError(f"{source}: motor poles {motor_poles}: a motor has an even number of "
                       "poles, at least 2")
    check_log_file(path)
    with path.open(encoding=ENCODING, errors=DECODE_ERRORS, newline="") as fh:
        names, arrays, protocol = _read_columns(fh, source)
    if "optical_rpm" not in names and "electrical_rpm" not in names:
        raise LogError(f"{source}: column missing: rotor speed ('Motor Optical Speed (RPM)' or "
                       "'Motor Electrical Speed (RPM)')")
    for q in SPARSE:
        if len(arrays[q]) and not np.any(np.isfinite(arrays[q])):
            raise LogError(f"{source}: column '{names[q]}': no data (every cell blank)")
    speed = _rotor_speed(arrays, motor_poles, source)
    t = arrays["time"]
    if len(t) < 10:
        raise LogError(f"{source}: {len(t)} data rows; a fit needs a logged test (≥ 10 rows)")
    order = _time_order(t, source)
    return StandLog(source, t[order], arrays["esc"][order], arrays["thrust"][order],
                    arrays["torque"][order], arrays["voltage"][order], arrays["current"][order],
                    speed[order], protocol)


def _time_order(t: np.ndarray, source: str) -> np.ndarray | slice:
    """Indices putting the samples in time order; a slice of them all (no copy) when they are.

    The stands' software stamps each sample; its first samples can be written out of order
    (seen in published RCbenchmark logs): sort by time, refuse only a repeated stamp."""
    if np.all(np.diff(t) > 0):
        return slice(None)
    order = np.argsort(t, kind="stable")
    if np.any(np.diff(t[order]) <= 0):
        bad = int(order[int(np.argmax(np.diff(t[order]) <= 0)) + 1]) + 2
        raise LogError(f"{source}: row {bad}, column 'Time': time stamp repeated")
    return order


def _rotor_speed(arrays: dict[str, np.ndarray], motor_poles: int | None,
                 source: str) -> np.ndarray:
    """Rotor speed (rad/s): the optical sensor where it holds data, else the electrical speed
    column. Tyto/RCbenchmark software writes that column already in rotor speed (it divides by the
    pole count set in its settings; checked on a published 9-inch log, whose fit gives C_T0 ≈ 0.11
    this way and 49× that divided again by 7 pole pairs): it is divided by the pole pairs only
    when ``motor_poles`` is given, for a log of the raw commutation frequency."""
    optical = arrays.get("optical_rpm")
    if optical is not None and np.nanmax(np.abs(optical), initial=0.0) > 0:
        speed = optical
    elif "electrical_rpm" in arrays:
        speed = arrays["electrical_rpm"] / (motor_poles / 2 if motor_poles else 1.0)
    else:
        raise LogError(f"{source}: column 'Motor Optical Speed (RPM)': no data")
    if np.any(~np.isfinite(speed)):
        row = int(np.argmax(~np.isfinite(speed))) + 2
        raise LogError(f"{source}: row {row}, rotor speed column: not a number")
    return np.abs(speed)


# ------------------------------------------------------------------------------------------------
# Segmentation: plateaus and steps
# ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Plateau:
    """Rows ``[start, stop)`` held at one ESC signal, and their settled means (SI)."""

    start: int
    stop: int
    esc_us: float
    thrust_n: float
    torque_nm: float
    voltage_v: float
    current_a: float
    speed_rad_s: float


def _mean(x: np.ndarray) -> float:
    """Mean of the samples present (NaN marks a blank cell); NaN where none is."""
    ok = np.isfinite(x)
    return float(np.mean(x[ok])) if np.any(ok) else math.nan


def plateaus(log: StandLog, min_plateau_s: float = 0.5, settled_fraction: float = 0.5
             ) -> list[Plateau]:
    """The runs of constant ESC signal lasting ≥ ``min_plateau_s``, with the means of their
    last ``settled_fraction`` (of the samples present: blank cells are skipped)."""
    change = np.flatnonzero(np.abs(np.diff(log.esc_us)) > 0.5) + 1
    bounds = np.concatenate([[0], change, [len(log.esc_us)]])
    starts, stops = bounds[:-1], bounds[1:]
    held = (stops - starts >= 3) & (log.time_s[stops - 1] - log.time_s[starts] >= min_plateau_s)
    _check_count(log, int(np.count_nonzero(held)))
    out = []
    for a, b in zip(starts[held], stops[held], strict=True):
        s = slice(a + int((b - a) * (1 - settled_fraction)), b)
        out.append(Plateau(int(a), int(b), float(log.esc_us[a]),
                           *(_mean(x[s]) for x in (log.thrust_n, log.torque_nm, log.voltage_v,
                                                   log.current_a, log.speed_rad_s))))
    return out


def _check_count(log: StandLog, count: int) -> None:
    """LogError for more steady points than :data:`MAX_STEADY_POINTS`."""
    if count > MAX_STEADY_POINTS:
        raise LogError(f"{log.source}: {count} steady points (held ESC signals or averaged "
                       f"rows), over the {MAX_STEADY_POINTS} of any stand's step test: not a "
                       "step test's log")


def steady_points(log: StandLog, min_plateau_s: float = 0.5, settled_fraction: float = 0.5
                  ) -> tuple[list[Plateau], SteadySource]:
    """The log's steady points and where they came from (module docstring): its plateaus; or,
    for a log without any plateau whose rows are a median ``min_plateau_s`` or more apart, every
    row (a stand's averaged row per step, each a one-row "plateau")."""
    found = plateaus(log, min_plateau_s, settled_fraction)
    if found or float(np.median(np.diff(log.time_s))) < min_plateau_s:
        return found, "plateaus"
    _check_count(log, len(log.time_s))
    return [Plateau(i, i + 1, float(log.esc_us[i]), float(log.thrust_n[i]),
                    float(log.torque_nm[i]), float(log.voltage_v[i]), float(log.current_a[i]),
                    float(log.speed_rad_s[i])) for i in range(len(log.time_s))], "averaged rows"


# ------------------------------------------------------------------------------------------------
# Fits
# ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Residual:
    """Goodness of one fit: RMS and largest absolute residual, in the fitted quantity's unit,
    and the RMS relative to the data's RMS; ``part``: the part of :data:`PARTS` it fits."""

    quantity: str
    unit: str
    rms: float
    max_abs: float
    relative_rms: float
    points: int
    part: str = ""


def _residual(part: str, quantity: str, unit: str, data: np.ndarray, fit: np.ndarray
              ) -> Residual:
    r = data - fit
    scale = float(np.sqrt(np.mean(data**2))) or 1.0
    rms = float(np.sqrt(np.mean(r**2)))
    return Residual(quantity, unit, rms, float(np.max(np.abs(r))), rms / scale, len(r), part)


@dataclass(frozen=True)
class StepFit:
    """One step response: start time (s), ESC signal before and after (µs), fitted τ (s), the
    speed it settles at (rad/s), the RMS of the fit (rad/s)."""

    time_s: float
    esc_from_us: float
    esc_to_us: float
    time_constant_s: float
    final_speed_rad_s: float
    rms_rad_s: float


@dataclass(frozen=True)
class PropulsionFit:
    """Everything fitted from one log.

    Attributes:
        source: the log's file name. plateaus: the steady points used.
        ct0, cp0: static thrust and power coefficients (UIUC definitions, n in rev/s).
        kv_rpm_per_v, resistance_ohm, no_load_current_a: Drela's first-order motor.
        open_circuit_voltage_v, internal_resistance_ohm: the battery (through its leads).
        time_constant_s: median of the resolved step responses, or None.
        rotor_inertia_kgm2: the rotor's inertia from the steps (module docstring), or None.
        steps: every step fitted. residuals: one per fit.
        steady_source: "plateaus" or "averaged rows" (:func:`steady_points`).
        esc_protocol, esc_range: the ESC signal's protocol and the duty range ``(zero, full)``
            used (µs for PWM, command values for DShot).
        parts: the parts of :data:`PARTS` asked for (a part not asked for is NaN); refused:
            (part, why) of each part asked for whose fit is refused (its values are kept, to be
            shown, and left out of the section).
    """

    source: str
    diameter_m: float
    air_density_kg_m3: float
    plateaus: tuple[Plateau, ...]
    ct0: float
    cp0: float
    kv_rpm_per_v: float
    resistance_ohm: float
    no_load_current_a: float
    open_circuit_voltage_v: float
    internal_resistance_ohm: float
    time_constant_s: float | None
    rotor_inertia_kgm2: float | None
    steps: tuple[StepFit, ...]
    residuals: tuple[Residual, ...]
    steady_source: SteadySource = "plateaus"
    esc_protocol: str = "pwm"
    esc_range: tuple[float, float] = ESC_RANGES["pwm"]
    parts: tuple[str, ...] = PARTS
    refused: tuple[tuple[str, str], ...] = ()

    def status(self, part: str) -> PartStatus:
        """Whether ``part`` was fitted, refused, or not asked for."""
        if part not in self.parts:
            return "not fitted"
        return "refused" if part in dict(self.refused) else "fitted"

    @property
    def fitted(self) -> tuple[str, ...]:
        """The parts fitted and not refused (those the section holds)."""
        return tuple(p for p in PARTS if self.status(p) == "fitted")

    def section(self, shape: str | None = None) -> dict[str, Any]:
        """The airframe's ``propulsion:`` section (the keys of the propeller model): the parts
        :attr:`fitted` only (a refused part, or one not asked for, is left to the user: a
        datasheet's motor, the pack's label).

        Args:
            shape: a shipped propeller dataset (:func:`casadrone.propulsion.propeller_data`)
                whose fitted C_T(J), C_P(J) polynomials, scaled to this log's static values, give
                the dependence on the advance ratio; None: static coefficients only.
        """
        source = f"{self.source} (casadrone fit-propulsion)"
        ct, cp = shaped_coefficients(self.ct0, self.cp0, shape)
        propeller: dict[str, Any] = {
            "diameter_m": _round(self.diameter_m),
            "ct_coefficients": [_round(c) for c in ct],
            "cp_coefficients": [_round(c) for c in cp],
        }
        if self.rotor_inertia_kgm2 is not None and self.status("motor") == "fitted":
            propeller["rotor_inertia_kgm2"] = _round(self.rotor_inertia_kgm2)
        if shape:  # the shape holds to its data's largest J only: the limit lap keeps to it
            propeller["max_advance_ratio"] = _round(data_advance_ratio(shape))
        propeller["data"] = (f"{source}: static values; J-dependence of {shape} scaled to them"
                             if shape else
                             f"{source}: static coefficients only (a static stand sees J = 0)")
        parts = {
            "propeller": propeller,
            "motor": {
                "kind": "dc",
                "kv_rpm_per_v": _round(self.kv_rpm_per_v),
                "resistance_ohm": _round(self.resistance_ohm),
                "no_load_current_a": _round(self.no_load_current_a),
                "data": source,
            },
            "battery": {
                "open_circuit_voltage_v": _round(self.open_circuit_voltage_v),
                "internal_resistance_ohm": _round(self.internal_resistance_ohm),
                "data": source,
            },
        }
        return {"model": "propeller", **{p: parts[p] for p in self.fitted}}

    def part_values(self, part: str) -> dict[str, float]:
        """The fitted values of ``part`` (SI; KV in rpm/V), refused or not."""
        return {name: getattr(self, name) for name in PART_VALUES[part]}

    def as_dict(self, shape: str | None = None) -> dict[str, Any]:
        """JSON-ready summary: each part (status, why refused, values, residuals), the section
        of the fitted parts, every residual, every step."""
        why = dict(self.refused)
        return {
            "source": self.source,
            "plateaus": len(self.plateaus),
            "steady_points_from": self.steady_source,
            "esc": {"protocol": self.esc_protocol, "zero_duty": self.esc_range[0],
                    "full_duty": self.esc_range[1]},
            "parts": [{"part": p, "status": self.status(p), "reason": why.get(p),
                       "values": self.part_values(p) if p in self.parts else {},
                       "residuals": [vars(r) for r in self.residuals if r.part == p]}
                      for p in PARTS],
            "propulsion": self.section(shape),
            "residuals": [vars(r) for r in self.residuals],
            "steps": [vars(s) for s in self.steps],
        }


def shaped_coefficients(ct0: float, cp0: float, shape: str | None
                        ) -> tuple[list[float], list[float]]:
    """C_T(J), C_P(J) polynomial coefficients: ``[ct0]``, ``[cp0]`` without a shape; with one,
    the shape dataset's quadratic fits (the shipped fit's points and weights) each scaled so that
    its static value is the measured one — the measured propeller is assumed to lose thrust and
    power with the advance ratio in the same proportion as the dataset's."""
    if shape is None:
        return [ct0], [cp0]

    points = fit_points(propeller_data(shape))
    J, ct, cp = points[:, 0], points[:, 2], points[:, 3]
    c_t, c_p = fit_coefficients(J, ct), fit_coefficients(J, cp)
    return [c * ct0 / c_t[0] for c in c_t], [c * cp0 / c_p[0] for c in c_p]


def _round(x: float) -> float:
    return float(f"{x:.6g}")


def _fit_propeller(p: list[Plateau], D: float, rho: float) -> tuple[float, float, list[Residual]]:
    n = np.array([q.speed_rad_s for q in p]) / (2 * math.pi)
    T = np.array([q.thrust_n for q in p])
    Q = np.array([q.torque_nm for q in p])
    xT = rho * n**2 * D**4
    xQ = rho * n**2 * D**5 / (2 * math.pi)  # Q = C_P ρ n² D⁵ / 2π
    ct0 = float(xT @ T / (xT @ xT))
    cp0 = float(xQ @ Q / (xQ @ xQ))
    return ct0, cp0, [_residual("propeller", "thrust", "N", T, ct0 * xT),
                      _residual("propeller", "torque", "N·m", Q, cp0 * xQ)]


def _fit_motor(p: list[Plateau], duty: np.ndarray) -> tuple[float, float, float, list[Residual]]:
    w = np.array([q.speed_rad_s for q in p])
    Vm = duty * np.array([q.voltage_v for q in p])
    Im = np.array([q.current_a for q in p]) / duty
    Q = np.array([q.torque_nm for q in p])
    A = np.column_stack([w, Im])
    (inv_kv, R), *_ = np.linalg.lstsq(A, Vm, rcond=None)
    kv = 1.0 / inv_kv  # rad/s per V
    i0 = float(np.mean(Im - kv * Q))
    return (kv * 60 / (2 * math.pi), float(R), i0,
            [_residual("motor", "motor voltage", "V", Vm, A @ np.array([inv_kv, R])),
             _residual("motor", "motor current", "A", Im, kv * Q + i0)])


def _fit_battery(p: list[Plateau]) -> tuple[float, float, Residual]:
    V = np.array([q.voltage_v for q in p])
    I = np.array([q.current_a for q in p])
    slope, v0 = np.polyfit(I, V, 1)
    return float(v0), float(-slope), _residual("battery", "bus voltage", "V", V,
                                               v0 + slope * I)


def _fit_step(log: StandLog, before: Plateau, after: Plateau) -> StepFit | None:
    from scipy.optimize import least_squares

    s = slice(after.start, after.stop)
    t = log.time_s[s] - log.time_s[after.start - 1]  # the step is applied at the previous sample
    w = log.speed_rad_s[s]
    w0, winf = before.speed_rad_s, after.speed_rad_s
    if abs(winf - w0) < 0.05 * max(winf, w0, 1.0):
        return None  # too small a step to see a time constant through the noise

    def model(tau):
        return winf + (w0 - winf) * np.exp(-t / tau[0])

    dt = float(np.median(np.diff(t)))
    sol = least_squares(lambda x: model(x) - w, x0=[max(3 * dt, 0.02)], bounds=([1e-4], [5.0]))
    tau = float(sol.x[0])
    if np.count_nonzero(t <= 3 * tau) < MIN_STEP_SAMPLES:
        return None  # the sampling does not resolve this response
    rms = float(np.sqrt(np.mean((model(sol.x) - w) ** 2)))
    return StepFit(float(log.time_s[after.start]), before.esc_us, after.esc_us, tau, winf, rms)


def _tared(points: list[Plateau], esc_min_us: float) -> list[Plateau]:
    """Load-cell readings relative to the mean of the unpowered plateaus with the rotor at rest
    (the stand's tare; a rotor still coasting down still loads the cells), signed so
    that thrust and torque are positive at the highest ESC signal (a stand logs them with the sign
    of its mounting)."""
    import dataclasses

    if not points:
        return []
    top_speed = max(q.speed_rad_s for q in points)
    idle = [q for q in points if q.esc_us <= esc_min_us and q.speed_rad_s < 0.01 * top_speed]
    t0 = float(np.mean([q.thrust_n for q in idle])) if idle else 0.0
    q0 = float(np.mean([q.torque_nm for q in idle])) if idle else 0.0
    top = max(points, key=lambda q: q.esc_us)  # the sign where the loads are far above noise
    st = np.sign(top.thrust_n - t0) or 1.0
    sq = np.sign(top.torque_nm - q0) or 1.0
    return [dataclasses.replace(q, thrust_n=float(st * (q.thrust_n - t0)),
                                torque_nm=float(sq * (q.torque_nm - q0))) for q in points]


#: Physically possible range of each fitted value, and the columns it comes from: a fit outside
#: is refused (a sign or unit problem of the log), never written into an airframe.
PHYSICAL: dict[str, tuple[str, float, float, str]] = {
    "ct0": ("static thrust coefficient C_T0", 0.01, 0.4, "Thrust, rotor speed"),
    "cp0": ("static power coefficient C_P0", 0.005, 0.4, "Torque, rotor speed"),
    "kv": ("motor KV (rpm/V)", 50.0, 30000.0, "Voltage, Current, rotor speed, ESC signal"),
    "R": ("motor resistance (Ω)", 1e-3, 5.0, "Voltage, Current, rotor speed, ESC signal"),
    "i0": ("no-load current (A)", 0.0, 20.0, "Current, Torque, ESC signal"),
    "v0": ("open-circuit voltage (V)", 1.0, 60.0, "Voltage, Current"),
    "r_int": ("battery internal resistance (Ω)", 0.0, 1.0, "Voltage, Current"),
}


#: The :data:`PHYSICAL` keys of each part.
PART_PHYSICAL: dict[str, tuple[str, ...]] = {
    "propeller": ("ct0", "cp0"), "motor": ("kv", "R", "i0"), "battery": ("v0", "r_int")}
#: Why a motor fit can be refused on a sound log: what its model takes of the ESC.
MOTOR_HINT = ("; the motor fit takes the ESC as a lossless buck whose duty is linear in the ESC "
              "signal over --esc-min-us..--esc-max-us, which DShot ESCs seldom are (their "
              "firmware's throttle mapping and active freewheeling): the propeller fit does not "
              "need it (--part propeller)")


def _physical_problem(part: str, values: dict[str, float]) -> str | None:
    """Why the fitted values of ``part`` are not physical (:data:`PHYSICAL`), or None."""
    for key in PART_PHYSICAL[part]:
        name, lo, hi, columns = PHYSICAL[key]
        value = values[key]
        if not lo <= value <= hi:
            hint = MOTOR_HINT if part == "motor" else ""
            return (f"columns {columns}: the fitted {name} is {value:.4g}, outside the physical "
                    f"{lo:g}-{hi:g} (check the columns' signs, units and tare{hint})")
    return None


def _blamed_part(problem: str) -> str:
    """The part a refusal of the section (``propulsion.<part>.<key>: ...``) falls on: the rotor
    inertia is the motor's (worked out with its K_V and R), else the part named."""
    if problem.startswith("propulsion.propeller.rotor_inertia_kgm2"):
        return "motor"
    named = problem.split(":")[0].split(".")
    return named[1] if len(named) > 1 and named[1] in PARTS else "propeller"


def _complete(p: Plateau) -> bool:
    return all(math.isfinite(x) for x in (p.thrust_n, p.torque_nm, p.voltage_v, p.current_a,
                                          p.speed_rad_s))


def fit_propulsion(log: StandLog, diameter_m: float, air_density_kg_m3: float = RHO_ISA,
                   esc_min_us: float | None = None, esc_max_us: float | None = None,
                   min_plateau_s: float = 0.5, parts: tuple[str, ...] = PARTS) -> PropulsionFit:
    """Fit the propeller, motor, battery and motor time constant of :mod:`this module's
    <casadrone.thruststand>` docstring from a stand log.

    Each part of ``parts`` is fitted alone; a part whose values fall outside :data:`PHYSICAL`, or
    that the airframe schema would refuse (:func:`section_problem`), is reported in the result's
    ``refused`` with the reason, and the others are kept (a DShot log's propeller fits where its
    motor, seen through the lossless-ESC model, does not). The rotor inertia needs the motor and
    the battery (and the propeller's torque): without them it is not worked out.

    Args:
        esc_min_us: the ESC signal at zero duty; None: the low end of the log's protocol's
            range (:data:`ESC_RANGES`: 1000-2000 µs for PWM, 48-2047 for DShot).
        esc_max_us: the ESC signal at full duty; None: the high end of that range.
        parts: the parts of :data:`PARTS` to fit.

    Raises:
        LogError: fewer than three powered steady points, a point outside the ESC range, an
            option out of its range.
    """
    if not parts or not set(parts) <= set(PARTS):
        raise ValueError(f"parts: {parts!r}: choose among {', '.join(PARTS)}")
    if not DIAMETER_RANGE_M[0] <= diameter_m <= DIAMETER_RANGE_M[1]:
        raise LogError(f"{log.source}: propeller diameter {diameter_m} m outside 0.02-2 m")
    if not AIR_DENSITY_RANGE[0] <= air_density_kg_m3 <= AIR_DENSITY_RANGE[1]:
        raise LogError(f"{log.source}: air density {air_density_kg_m3} kg/m³ outside 0.3-1.5")
    lo, hi = ESC_RANGES[log.esc_protocol]
    esc_min_us = lo if esc_min_us is None else esc_min_us
    esc_max_us = hi if esc_max_us is None else esc_max_us
    unit = " µs" if log.esc_protocol == "pwm" else " (DShot)"
    for flag, value in (("--esc-min-us", esc_min_us), ("--esc-max-us", esc_max_us)):
        if not ESC_SIGNAL_RANGE[0] <= value <= ESC_SIGNAL_RANGE[1]:
            raise LogError(f"{log.source}: ESC signal {value:g}{unit} ({flag}) outside "
                           f"{ESC_SIGNAL_RANGE[0]:g}-{ESC_SIGNAL_RANGE[1]:g}")
    if not esc_min_us < esc_max_us:
        raise LogError(f"{log.source}: ESC range {esc_min_us:g}-{esc_max_us:g}{unit}: the zero "
                       "duty must be below the full duty (--esc-min-us, --esc-max-us)")
    with _quiet_numerics():
        try:
            return _fit(log, diameter_m, air_density_kg_m3, esc_min_us, esc_max_us,
                        min_plateau_s, tuple(p for p in PARTS if p in parts))
        except np.linalg.LinAlgError as exc:
            raise LogError(f"{log.source}: the steady points determine no fit ({exc})") from None


@contextmanager
def _quiet_numerics() -> Iterator[None]:
    """No numpy or scipy warning on stderr during a fit (an ill-conditioned regression, an
    overflow in a step fit): every fitted value is checked against :data:`PHYSICAL`, a NaN or inf
    included, and refused with a message naming its columns."""
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        yield


def _fit(log: StandLog, diameter_m: float, air_density_kg_m3: float, esc_min_us: float,
         esc_max_us: float, min_plateau_s: float, parts: tuple[str, ...]) -> PropulsionFit:
    """:func:`fit_propulsion` once its arguments are checked."""
    unit = " µs" if log.esc_protocol == "pwm" else " (DShot)"
    points, source = steady_points(log, min_plateau_s)
    allp = _tared([q for q in points if _complete(q)], esc_min_us)
    powered = [q for q in allp if q.esc_us > esc_min_us and q.speed_rad_s > 0 and q.current_a > 0]
    if len(powered) < 3:
        raise LogError(f"{log.source}: {len(powered)} powered steady points (ESC signal held "
                       f"≥ {min_plateau_s} s above {esc_min_us:g}{unit}, or averaged rows); "
                       "a fit needs ≥ 3")
    duty = np.array([(q.esc_us - esc_min_us) / (esc_max_us - esc_min_us) for q in powered])
    if np.any(duty > 1.0 + 1e-9):
        bad = powered[int(np.argmax(duty))]
        raise LogError(f"{log.source}: row {bad.start + 2}, column 'ESC signal': "
                       f"{bad.esc_us:g}{unit} above the ESC range's top {esc_max_us:g}{unit} "
                       "(--esc-max-us)")
    nan = math.nan
    ct0, cp0, res_prop = (_fit_propeller(powered, diameter_m, air_density_kg_m3)
                          if "propeller" in parts else (nan, nan, []))
    kv, R, i0, res_motor = _fit_motor(powered, duty) if "motor" in parts else (nan, nan, nan, [])
    v0, r_int, res_batt = _fit_battery(powered) if "battery" in parts else (nan, nan, None)
    values = dict(ct0=ct0, cp0=cp0, kv=kv, R=R, i0=i0, v0=v0, r_int=r_int)
    refused = {p: why for p in parts if (why := _physical_problem(p, values)) is not None}
    # a step response needs the time series between two plateaus: none from averaged rows
    steps = tuple(s for a, b in zip(allp[:-1], allp[1:], strict=True)
                  if source == "plateaus" and b.start == a.stop
                  and (s := _fit_step(log, a, b)) is not None)
    tau = float(np.median([s.time_constant_s for s in steps])) if steps else None
    inertia = (_rotor_inertia(steps, cp0, kv, R, r_int, diameter_m, air_density_kg_m3,
                              esc_min_us, esc_max_us)
               if set(PARTS) <= set(parts) - set(refused) else None)
    residuals = (*res_prop, *res_motor, *([res_batt] if res_batt else []))
    fit = PropulsionFit(log.source, diameter_m, air_density_kg_m3, tuple(powered), ct0, cp0,
                        kv, R, i0, v0, r_int, tau, inertia, steps, residuals, source,
                        log.esc_protocol, (esc_min_us, esc_max_us), parts,
                        tuple(refused.items()))
    return _schema_checked(fit)


def _schema_checked(fit: PropulsionFit) -> PropulsionFit:
    """``fit`` with each part the airframe schema refuses (:func:`section_problem` on the
    section of the fitted parts) refused in turn, naming the key; the rotor inertia dropped
    with the motor it was worked out with."""
    import dataclasses

    while fit.fitted:
        problem = fitted_problem(fit)
        if problem is None:
            break
        part = _blamed_part(problem)
        if part not in fit.fitted:  # a problem of no part this fit can drop
            raise LogError(f"{fit.source}: the fitted section is not a physical propulsion "
                           f"system, {problem} (check the columns' units, signs and tare)")
        why = (f"the fitted section is not a physical propulsion system, {problem} (check the "
               "columns' units, signs and tare)")
        fit = dataclasses.replace(
            fit, refused=(*fit.refused, (part, why)),
            rotor_inertia_kgm2=None if part == "motor" else fit.rotor_inertia_kgm2)
    return fit


def fitted_problem(fit: PropulsionFit, shape: str | None = None) -> str | None:
    """The first reason the airframe schema refuses the fitted parts (their section with
    ``shape``, :meth:`PropulsionFit.section`): the whole section's (:func:`section_problem`)
    when every part is fitted, else each part's own schema (a section of some parts is not a
    whole ``propulsion:`` section: the user adds the others)."""
    from pydantic import BaseModel, ValidationError

    section = fit.section(shape)
    if fit.fitted == PARTS:
        return section_problem(section, fit.air_density_kg_m3)
    schemas: dict[str, type[BaseModel]] = {
        "propeller": PropellerConfig, "motor": MotorConfig, "battery": BatteryConfig}
    for part in fit.fitted:
        try:
            schemas[part].model_validate(section[part])
        except ValidationError as exc:
            key, message = error_pairs(exc, schemas[part])[0]
            return f"propulsion.{part}.{key}: {message}"
    return None


def section_problem(section: dict[str, Any], air_density_kg_m3: float) -> str | None:
    """The first reason the airframe schema would refuse a fitted ``propulsion:`` section, as
    ``propulsion.key: message``; None if it loads. :data:`PHYSICAL` bounds each value alone; the
    schema's bounds join them (casadrone.config.propulsion: the static figure of merit
    √(2/π) C_T0^1.5/C_P0 ≤ 1 of momentum theory, the DC motor's mechanical time constant, tips
    below the speed of sound), so a section passing :data:`PHYSICAL` can still be impossible: a
    torque column read low gives a C_P0 inside its range but a rotor above the ideal."""
    from pydantic import ValidationError

    try:
        cfg = PropulsionConfig.model_validate(section)
    except ValidationError as exc:
        key, message = error_pairs(exc, PropulsionConfig)[0]
        return f"propulsion.{key}: {message}"
    found = airframe_problems(cfg, mass_kg=None, rho=air_density_kg_m3, prop_diameter_mm=None,
                              mass_key="mass_kg")
    return f"{found[0][0]}: {found[0][1]}" if found else None


def _rotor_inertia(steps: tuple[StepFit, ...], cp0: float, kv_rpm_per_v: float, R: float,
                   r_int: float, D: float, rho: float, esc_min_us: float, esc_max_us: float
                   ) -> float | None:
    """Median over the powered steps of τ (∂Q_p/∂ω − ∂Q_m/∂ω) at the step's end (module
    docstring)."""
    kv = kv_rpm_per_v * 2 * math.pi / 60
    values = []
    for s in steps:
        d = (s.esc_to_us - esc_min_us) / (esc_max_us - esc_min_us)
        w = s.final_speed_rad_s
        if d <= 0 or w <= 0:
            continue
        qp = cp0 * rho * (w / (2 * math.pi)) ** 2 * D**5 / (2 * math.pi)
        values.append(s.time_constant_s * (2 * qp / w + 1 / (kv**2 * (R + r_int * d**2))))
    return float(np.median(values)) if values else None
