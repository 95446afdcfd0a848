"""What every stage's results share: one word for how a flight ends, the record the optimiser
keeps of a candidate, and ``as_dict`` (a result as plain data, what every ``--json`` prints).

Light on purpose (no CasADi, no pymoo): the optimiser, the store and the report read records
without importing the chain.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

#: The one word for how anything flown ends (a lap, an evaluation, a benchmark row, a limit lap):
#: ``completed``, or ``failed`` with a reason.
Status = Literal["completed", "failed"]


class AsDict:
    """``as_dict()`` for a frozen dataclass result: its fields as plain data (nested results and
    containers converted; numpy arrays left as they are: :func:`casadrone.cli.common.jsonable`
    makes them JSON). ``_omit`` names fields left out (trajectories, matrices kept elsewhere);
    ``_keys`` renames fields whose key carries its unit (``thrusts`` → ``thrusts_N``);
    ``_properties`` names derived values added after the fields (``lap_time_s``).

    Every command's ``--json`` is its result's ``as_dict()``, beside what the command was asked
    (the airframe, the track): ``tests/integration/test_json_as_dict.py``."""

    _omit: tuple[str, ...] = ()
    _keys: ClassVar[Mapping[str, str]] = {}
    _properties: ClassVar[tuple[str, ...]] = ()

    def as_dict(self) -> dict[str, Any]:
        assert dataclasses.is_dataclass(self)
        out = {self._keys.get(f.name, f.name): _plain(getattr(self, f.name))
               for f in dataclasses.fields(self) if f.name not in self._omit}
        return out | {name: _plain(getattr(self, name)) for name in self._properties}


def _plain(value: Any) -> Any:
    if isinstance(value, AsDict):
        return value.as_dict()
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if callable(getattr(value, "model_dump", None)):  # a pydantic model (a config section)
        return value.model_dump()
    return value


@dataclass(frozen=True)
class Record(AsDict):
    """One candidate's result as the optimiser keeps it (the run history): θ, how it ended, and
    its indices when completed, else the stage and reason it failed
    (:class:`casadrone.evaluate.Evaluation` adds what only the evaluating process has)."""

    theta: dict[str, float]
    status: Status
    stage: str = ""  # "geometry", "trim", "control", "lap" or "" when completed
    reason: str = ""
    indices: dict[str, float] = field(default_factory=dict)
    wall_time_s: float = 0.0

    @property
    def completed(self) -> bool:
        return self.status == "completed"
