"""The parts catalogue: propellers, motors and packs a build chooses from, each row cited and kept
raw beside its fit (docs/parts.md).

* :mod:`casadrone.parts.records`: the frozen records (:class:`PropellerPart`,
  :class:`MotorPart`, :class:`PackPart`) and the physics they carry (blade Reynolds number, pack
  open-circuit voltage).
* :mod:`casadrone.parts.catalogue`: the shipped data (``casadrone/data/parts``), the propeller
  fits and :class:`Catalogue`, the parts by name.

Static data, below the configuration: :mod:`casadrone.config.parts` turns a part into the
``propulsion:`` section an airframe uses and reads a user's own parts file.
"""

from __future__ import annotations

from casadrone.parts.catalogue import Catalogue, propeller_points, shipped_catalogue
from casadrone.parts.records import KINDS, MotorPart, PackPart, Part, PropellerPart

__all__ = ["KINDS", "Catalogue", "MotorPart", "PackPart", "Part", "PropellerPart",
           "propeller_points", "shipped_catalogue"]
