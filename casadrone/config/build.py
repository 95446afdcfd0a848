"""The build problem file (``problems/build-*.yaml``): a co-design problem whose airframe flies
parts chosen from a catalogue (:mod:`casadrone.build`).

A problem file with a ``build:`` section beside the co-design problem's keys
(:class:`casadrone.config.codesign.CodesignProblemConfig`): the airframe is the template (of the
``propeller`` kind, ``mass_model: components``), ``variables`` the geometry co-designed for every
combination, ``codesign`` how each co-design is posed, ``backend`` where the combinations are
co-designed side by side. The ``build:`` section names the parts to consider: names of the
shipped catalogue (``casadrone parts``) or of a user parts file (``parts_file``), or ``all`` of
a kind, filtered by diameter and blades for propellers and by cells for packs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from pydantic import Field

from casadrone.config.codesign import CodesignProblemConfig
from casadrone.config.io import Schema

#: Largest tip Mach number a propeller may reach at its motor's no-load speed on the full pack
#: (K_V · V_full · π D / 60 over the speed of sound): 5-inch racing propellers are flown at
#: 40 000-45 000 rpm unloaded on 6S with 1700-1800 KV motors (Mach 0.8-0.9); beyond it the
#: blade tips go transonic, where the catalogue's low-speed fits (UIUC, Mach < 0.3) say nothing.
DEFAULT_MAX_TIP_MACH = 0.9
#: Speed of sound in the ISA sea-level air (m/s), for the tip Mach number.
SPEED_OF_SOUND_M_S = 340.3
#: A propeller's mass (kg) where the catalogue has none (the UIUC database weighs none): a
#: 5-inch three-blade racing propeller weighs 3.5-4.5 g (makers' listings: HQProp 5x4.3x3
#: 4.1 g, Gemfan 51466 4.2 g); assumed, and stated in the bill of materials.
DEFAULT_PROPELLER_MASS_KG = 0.004

Names = tuple[str, ...] | Literal["all"]


class BuildSettings(Schema):
    """The parts a build chooses from and how it searches them."""

    propellers: Names = Field(description="propeller names, or all (filtered by diameter_in "
                              "and blades)")
    motors: Names = Field(description="motor names, or all")
    packs: Names = Field(description="pack names, or all (filtered by cells)")
    parts_file: Path | None = Field(None, description="a user parts file (casadrone parts "
                                    "--file) whose parts join the shipped catalogue")
    diameter_in: tuple[float, float] | None = Field(
        None, description="[lowest, highest] propeller diameter (inch) of propellers: all")
    blades: int | None = Field(None, ge=1, le=12, description="blades of propellers: all")
    cells: int | None = Field(None, ge=1, le=24, description="cells of packs: all")
    laps: int | None = Field(None, ge=1, le=20, description="laps of the race (default: the "
                             "track's laps); the geometry is co-designed on the track as given")
    rank: int = Field(3, ge=1, le=1000, description="builds ranked exactly: a combination is "
                      "pruned when its bound exceeds the rank-th best race time found so far")
    max_tip_mach: float = Field(DEFAULT_MAX_TIP_MACH, gt=0, le=2,
                                description="largest tip Mach number at the motor's no-load "
                                "speed on the full pack (DEFAULT_MAX_TIP_MACH)")
    propeller_mass_kg: float = Field(DEFAULT_PROPELLER_MASS_KG, gt=0, le=1,
                                     description="a propeller's mass where its part has none "
                                     "(assumed; DEFAULT_PROPELLER_MASS_KG)")
    certify: bool = Field(True, description="certify the ranked builds' co-design points "
                          "(casadrone.codesign.certificate)")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        d = v.get("diameter_in")
        if d is not None and not 0 < d[0] <= d[1]:
            return [("diameter_in", f"give [lowest, highest] with 0 < lowest <= highest, got "
                     f"{list(d)}")]
        return []


class BuildProblemConfig(CodesignProblemConfig):
    """A co-design problem with a ``build:`` section (see the module docstring)."""

    build: BuildSettings = Field(description="the parts a build chooses from")
