"""evaluate's θ and its template: θ from one airframe is not flown on another's mass and drag by
accident."""

from __future__ import annotations

import pickle
from dataclasses import replace

import pytest

from casadrone.airframe import THETA_KEYS
from casadrone.config.airframe import load_airframe
from casadrone.evaluate import Theta, default_setup, evaluate, theta_of


def test_theta_of_is_a_dict_of_the_decision_variables_tagged_with_the_airframe():
    cfg = load_airframe("HS210")
    theta = theta_of(cfg)
    assert isinstance(theta, dict) and list(theta) == list(THETA_KEYS)
    assert theta["lambda_a_mm"] == cfg.lambda_a_mm and theta.airframe == "HS210"
    again = pickle.loads(pickle.dumps(theta))  # travels to worker processes intact
    assert again == theta and again.airframe == "HS210"


def test_theta_of_another_airframe_is_refused():
    setup = default_setup()  # SY250's template
    with pytest.raises(ValueError, match=r"HS210's geometry with SY250's mass") as info:
        evaluate(theta_of(load_airframe("HS210")), setup)
    assert "default_setup('HS210')" in str(info.value)
    # the template that matches is accepted (no exception before the chain runs)
    hs = load_airframe("HS210")
    assert replace(setup, template=hs).template.name == theta_of(hs).airframe


def test_plain_dict_means_it():
    # the optimiser's θ: a plain dict on the study's template, never refused
    theta = dict(theta_of(load_airframe("HS210")))
    assert not isinstance(theta, Theta) and getattr(theta, "airframe", None) is None
    ev = evaluate({**theta, "alpha_deg": 1.0}, default_setup())  # refused geometry, fast
    assert ev.status == "failed" and ev.stage == "geometry"
