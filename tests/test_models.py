"""Soil models: closed forms, analytic Jacobians against complex-step derivatives, metadata."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from soilstats.fitting.jacobian import (
    complex_step_jacobian,
    make_jacobian,
    ridders_jacobian,
)
from soilstats.models import BEKKER, BERNSTEIN, JANOSI, MODELS, MOHR_COULOMB, REECE, get_model

RNG = np.random.default_rng(7)
B = RNG.choice([0.025, 0.05, 0.075], 40)
Z = RNG.uniform(1e-3, 0.08, 40)
SIGMA = RNG.uniform(2e3, 2e4, 40)
J = RNG.uniform(0, 0.05, 40)

CASES = [
    (BEKKER, np.vstack([B, Z]), (-9.8e3, 1.2e6, 0.8)),
    (BERNSTEIN, Z, (1.1e6, 0.9)),
    (REECE, np.vstack([B, Z]), (2.0e3, 4.0e5, 1.1)),
    (JANOSI, np.vstack([SIGMA, J]), (120.0, 32.0, 0.01)),
    (MOHR_COULOMB, SIGMA, (70.0, 30.5)),
]


@pytest.mark.parametrize(("model", "x", "theta"), CASES, ids=lambda c: getattr(c, "name", ""))
def test_analytic_jacobian_matches_complex_step(model, x, theta):
    analytic = model.jac(x, *theta)
    # The complex step needs complex-capable code: evaluate the formulas directly.
    reference = ridders_jacobian(model.func, x, np.array(theta, float))
    np.testing.assert_allclose(analytic, reference, rtol=1e-6, atol=1e-9 * np.abs(analytic).max())
    assert analytic.shape == (x.shape[-1], model.n_params)


def test_closed_forms():
    assert BEKKER.func((np.array([0.05]), np.array([0.01])), 1e3, 1e6, 1.0)[0] == pytest.approx(
        (1e3 / 0.05 + 1e6) * 0.01
    )
    assert BERNSTEIN.func(np.array([0.04]), 2e5, 0.5)[0] == pytest.approx(2e5 * 0.2)
    assert REECE.func((np.array([0.1]), np.array([0.05])), 1e3, 2e4, 1.0)[0] == pytest.approx(
        (1e3 + 2e4 * 0.1) * 0.5
    )
    # Janosi: at j = K the curve reaches 1 − 1/e of the Mohr–Coulomb limit (Eq. 13 with −j/K).
    tau = JANOSI.func((np.array([1e4]), np.array([0.02])), 100.0, 45.0, 0.02)[0]
    assert tau == pytest.approx((100.0 + 1e4) * (1 - np.exp(-1)))
    assert MOHR_COULOMB.func(np.array([1e4]), 50.0, 45.0)[0] == pytest.approx(1e4 + 50.0)


def test_sinkage_models_are_zero_without_contact():
    z = np.array([-1e-4, 0.0, 1e-3])
    p = BEKKER.func((np.full(3, 0.05), z), 1e3, 1e6, 0.8)
    assert p[0] == 0 and p[1] == 0 and p[2] > 0
    assert np.all(np.isfinite(BEKKER.jac((np.full(3, 0.05), z), 1e3, 1e6, 0.8)))


def test_metadata_and_lookup():
    assert BEKKER.param_names == ("kc", "kphi", "n")
    assert BERNSTEIN.param_names == ("k", "n")
    assert REECE.param_names == ("k1", "k2", "n")
    assert JANOSI.param_names == ("c", "phi", "K")
    assert MOHR_COULOMB.param_names == ("c", "phi")
    for model in MODELS.values():
        assert len(model.units) == len(model.bounds) == model.n_params
        assert "Eq." in model.equation or model is REECE
    assert get_model("bekker") is BEKKER
    with pytest.raises(ValueError, match="choose one of"):
        get_model("bekkr")


def test_the_records_hold_what_the_layers_kept_in_lists():
    """The facts identification, bayes, the CLI and the studies each kept about a model,
    now read from its record (docs/conventions.md, "The model record")."""
    from soilstats.bayes import DEFAULT_PRIORS, SIMULATOR_FORMATS
    from soilstats.bayes.population_model import POPULATION_MODELS
    from soilstats.models import model_names
    from soilstats.models.priors import FLAT, NON_NEGATIVE, POSITIVE, Uniform
    from soilstats.study.spec import study_models

    assert model_names("sinkage") == ["bekker", "bernstein", "reece"]
    assert model_names("shear") == ["janosi", "mohr-coulomb"]
    assert study_models("sinkage") == ["bekker", "bernstein", "reece"]
    assert study_models("shear") == ["mohr-coulomb"]
    assert [m.name for m in MODELS.values() if m.min_plate_sizes == 2] == ["bekker", "reece"]
    assert {m.name: m.design_input for m in MODELS.values() if m.design_input} == {
        "bekker": "b_m",
        "reece": "b_m",
        "janosi": "sigma_Pa",
        "mohr-coulomb": "sigma_Pa",
    }
    assert POPULATION_MODELS == ("bekker", "bernstein", "janosi")
    assert dict(DEFAULT_PRIORS["bekker"]) == {"kc": FLAT, "kphi": POSITIVE, "n": POSITIVE}
    assert DEFAULT_PRIORS["janosi"] == {
        "c": NON_NEGATIVE,
        "phi": Uniform(0.0, 90.0),
        "K": POSITIVE,
    }
    scm = SIMULATOR_FORMATS["chrono-scm"]
    assert list(scm) == ["kphi", "kc", "n", "c", "phi", "K"]  # SCM's order of its inputs
    assert scm["kc"] == ("Bekker_Kc", "Pa/m^(n-1)") and scm["K"] == ("Janosi_shear", "m")
    assert [r.label for r in BEKKER.support] == ["n <= 0", "kc/b + kphi <= 0"]
    assert [r.label for r in JANOSI.support] == ["c < 0", "phi outside (0, 90) deg", "K <= 0"]
    assert BEKKER.modulus.modulus(0.05, -1e3, 1e5, 1.0) == -1e3 / 0.05 + 1e5
    assert MOHR_COULOMB.steady_state and not JANOSI.steady_state
    assert BEKKER.x_from({"b_m": [1.0], "z_m": [2.0]}).tolist() == [[1.0], [2.0]]


def test_a_record_refuses_facts_about_parameters_it_does_not_have():
    with pytest.raises(ValueError, match="not parameters"):
        dataclasses.replace(BERNSTEIN, name="x", priors={"kc": None})
    with pytest.raises(ValueError, match="kind must be one of"):
        dataclasses.replace(BERNSTEIN, name="x", kind="wheel")
    with pytest.raises(ValueError, match="do not match inputs"):
        dataclasses.replace(BERNSTEIN, name="x", columns=("b_m", "z_m"))


def test_complex_step_is_exact_and_fallback_detects_non_analytic_models():
    x = np.linspace(0.1, 2, 30)

    def analytic(x, a, b):
        return a * np.exp(-b * x)

    jac, method = make_jacobian(analytic, x, np.array([2.0, 0.7]))
    assert method == "complex-step"
    exact = np.column_stack([np.exp(-0.7 * x), -2.0 * x * np.exp(-0.7 * x)])
    np.testing.assert_allclose(jac(x, 2.0, 0.7), exact, rtol=1e-14)

    def non_analytic(x, a, b):  # abs() drops the imaginary part: complex step would be wrong
        return np.abs(a) * np.exp(-b * x)

    jac, method = make_jacobian(non_analytic, x, np.array([2.0, 0.7]))
    assert method == "ridders"
    np.testing.assert_allclose(jac(x, 2.0, 0.7), exact, rtol=1e-8)
    cs = complex_step_jacobian(non_analytic, x, np.array([2.0, 0.7]))
    assert not np.allclose(cs, exact)
