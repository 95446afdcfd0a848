"""The controller YAML (``configs/controllers/``): the LQR-I weights, the gain policy and the
perturbed-plant ensemble of the robustness check."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, field_validator

from casadrone.config.airframe import load_airframe
from casadrone.config.io import ConfigError, Schema, first_line, load, resolve_config

Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]



class StateWeights(Schema):
    """Diagonal LQR state weights, one per state group (units: 1/unit² of the state)."""

    position: tuple[NonNegative, NonNegative, NonNegative] = Field(
        (0.5, 0.5, 1.0),
        description="weights of the position error x, y, z (1/m²)",
    )
    velocity: tuple[NonNegative, NonNegative, NonNegative] = Field(
        (0.2, 0.2, 0.2),
        description="weights of the body velocity u, v, w (s²/m²)",
    )
    rates: tuple[NonNegative, NonNegative, NonNegative] = Field(
        (0.05, 0.05, 0.05),
        description="weights of the body rates p, q, r (s²/rad²)",
    )
    attitude: tuple[NonNegative, NonNegative, NonNegative] = Field(
        (2.0, 2.0, 4.0),
        description="weights of the Euler angles φ, θ, ψ (1/rad²)",
    )
    thrust: tuple[NonNegative, NonNegative, NonNegative, NonNegative] = Field(
        (0.0, 0.0, 0.0, 0.0),
        description="weights of the rotor thrusts T1…T4 (1/N²)",
    )


class RobustnessConfig(Schema):
    """Perturbed-plant ensemble of paper Appendix B."""

    n_plants: int = Field(
        50, ge=1, le=10000,
        description="number of perturbed plants in the ensemble",
    )
    dynamics_pct: float = Field(30.0, ge=0, lt=100, description="mass, inertia, drag spread (%)")
    coupling_pct: float = Field(
        20.0, ge=0, lt=100, description="thrust gain, time constant, arm geometry, κ spread (%)"
    )
    seed: int = Field(
        0,
        description="random seed of the perturbations (the same seed gives the same plants)",
    )


#: Gain policies (docs/concepts/chain.md#control). ``redesign``: every candidate's own LQR-I gain.
#: ``frozen-command``: the reference airframe's gain K (ESC commands from state error) flies every
#: candidate as is, so each is mixed as the reference would be. ``frozen-wrench``: the reference's
#: gain, re-expressed from state error to [collective thrust, roll, pitch, yaw torque] and mapped
#: to each candidate's four commands by its own allocation inverse
#: (:func:`casadrone.control.frozen_wrench_gain`).
GainPolicy = Literal["redesign", "frozen-command", "frozen-wrench"]
FROZEN_POLICIES = ("frozen-command", "frozen-wrench")


class ControllerConfig(Schema):
    """LQR-I controller: discrete design at ``sample_time_s``, identical for every candidate."""

    name: str = Field("default", description="name of the controller, shown in reports")
    sample_time_s: float = Field(
        0.01, gt=0, le=0.1,
        description="controller period Ts of the discrete LQR-I (s; paper: 100–240 Hz)",
    )
    q: StateWeights = Field(
        StateWeights(),
        description="diagonal LQR state weights, per state group",
    )
    q_integral: tuple[NonNegative, NonNegative, NonNegative, NonNegative] = Field(
        (0.05, 0.05, 0.1, 0.05), description="weights of ∫e for x, y, z, yaw"
    )
    r: tuple[Positive, Positive, Positive, Positive] = Field(
        (10.0, 10.0, 10.0, 10.0),
        description="LQR weights of the four ESC commands δ1…δ4 (dimensionless)",
    )
    gain_policy: GainPolicy = Field("redesign", description="redesign: each candidate's own "
                                    "gain; frozen-command / frozen-wrench: the reference's gain")
    reference_airframe: Path | None = Field(
        None, description="airframe YAML whose gain is frozen for all (frozen-* gain policies)"
    )
    robustness: RobustnessConfig = Field(
        RobustnessConfig(),
        description="the perturbed-plant ensemble of the robustness check (paper Appendix B)",
    )

    @field_validator("gain_policy", mode="before")
    @classmethod
    def _renamed_policy(cls, value: Any) -> Any:
        if value == "frozen":
            raise ValueError("'frozen' is now called 'frozen-command' (the reference gain frozen "
                             "in ESC-command space, flown through the reference's mixer); or use "
                             "'frozen-wrench' (frozen in thrust and torque space, each frame "
                             "mixed by its own allocation)")
        return value

    @property
    def frozen_gain(self) -> bool:
        """True when one reference gain flies every candidate (a frozen-* gain policy)."""
        return self.gain_policy in FROZEN_POLICIES

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        policy = v.get("gain_policy")
        if policy in FROZEN_POLICIES and v.get("reference_airframe", 0) is None:
            return [("reference_airframe", f"required when gain_policy is '{policy}'")]
        return []


def load_controller(
    path: str | Path | None = None, overrides: list[str] | None = None
) -> ControllerConfig:
    """Load a controller YAML or name; ``None`` gives ``configs/controllers/default.yaml``.

    Its ``reference_airframe`` is loaded too: a file that is no valid airframe (a controller, a
    track) is one line naming the controller and the key (ConfigError), not the referenced
    file's own line, which read as if the option given (``--controller``) were wrong."""
    source = resolve_config(path or "default", "controllers")
    ctrl = load(ControllerConfig, source, overrides)
    if ctrl.reference_airframe is not None:
        try:
            load_airframe(ctrl.reference_airframe)
        except ConfigError as exc:
            raise ConfigError([f"{source}: reference_airframe: {first_line(exc)}"]) from None
    return ctrl
