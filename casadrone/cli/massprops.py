"""``casadrone massprops``: an airframe's mass, centre of mass and inertia tensor."""

from __future__ import annotations

import typer

from casadrone.cli.common import (
    AirframeArg,
    JsonOpt,
    OverridesArg,
    app,
    print_json,
    reports_config_errors,
)
from casadrone.config.airframe import load_airframe
from casadrone.massprops import mass_properties


@app.command()
@reports_config_errors
def massprops(airframe: AirframeArg, overrides: OverridesArg = None,
              as_json: JsonOpt = False) -> None:
    """Mass (kg), centre of mass (m, from the arm hub) and inertia tensor (kg·m², about the centre
    of mass, body axes x nose, y left, z up) of an airframe: given (mass_model free) or computed
    from its parts for its geometry (mass_model components, e.g. SY250-components
    lambda_a_mm=140)."""
    cfg = load_airframe(airframe, overrides or [])
    mp = mass_properties(cfg)
    result = {"airframe": cfg.name, **mp.as_dict()}
    if as_json:
        print_json(result)
        return
    J = mp.inertia_kgm2
    typer.echo(f"{cfg.name}: mass model {mp.mass_model}, mass {mp.mass_kg:.4f} kg")
    typer.echo("centre of mass from the hub (m, x nose, y left, z up): "
               + "  ".join(f"{v:+.5f}" for v in mp.com_m))
    typer.echo("inertia about the centre of mass (kg·m², body axes):")
    for axis, row in zip("xyz", J, strict=True):
        typer.echo(f"  {axis}  " + "  ".join(f"{v:+.6e}" for v in row))
