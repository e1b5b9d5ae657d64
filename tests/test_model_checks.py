"""Every registered model through the same checks (issue #45, item 6).

A model added through its record (:func:`soilstats.register_model`) is checked here without
anyone adding it to a list: the cases are generated from the registry at collection time,
one test per (model, check), as scikit-learn's ``parametrize_with_checks`` runs every
estimator through its checks. The truth each check holds a record to is independent of the
record: finite differences (Ridders) for its Jacobian, its own bounds and support rules for
its starting values and priors, the rank of its Jacobian for its identifiability hook, and
the identity for the round trip through the posterior's sampling coordinates.

Data and parameters come from the record alone: each input column gets a plausible range
(:data:`INPUT_RANGES`; an unknown column 0.1 … 1), each parameter a point inside its bounds
(:func:`typical_theta`). Later layers add their own checks to :data:`CHECKS` (the wheel's
round trip goes where ``WHEEL_CHECKS`` is).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from soilstats.bayes.transforms import sampling_coordinates
from soilstats.fitting import identify
from soilstats.fitting.jacobian import ridders_jacobian
from soilstats.models import Model, get_model, model_names

N = 48
#: input column -> (low, high) of plausible values; b_m and sigma_Pa take DESIGN_LEVELS
#: levels, as a campaign's plates and normal loads do.
INPUT_RANGES = {
    "b_m": (0.025, 0.075),
    "z_m": (1e-3, 0.08),
    "sigma_Pa": (2e3, 2e4),
    "j_m": (1e-3, 0.05),
}
DESIGN_LEVELS = 3


def inputs(model: Model, levels: int = DESIGN_LEVELS, seed: int = 45) -> np.ndarray:
    """x for ``model`` (shape (k, N), or (N,) for one input), its design column at ``levels``
    levels."""
    rng = np.random.default_rng(seed)
    rows = []
    for column in model.columns or tuple(f"x{i}" for i in range(len(model.inputs))):
        low, high = INPUT_RANGES.get(column, (0.1, 1.0))
        if column == model.design_input or column == "b_m":
            rows.append(rng.choice(np.linspace(low, high, levels), N))
        else:
            rows.append(rng.uniform(low, high, N))
    return rows[0] if len(rows) == 1 else np.vstack(rows)


def typical_theta(model: Model) -> np.ndarray:
    """A point well inside every parameter's bounds: the middle of a finite range, one above
    a finite lower bound, 1 without bounds."""
    out = []
    for lo, hi in model.bounds:
        if np.isfinite(lo) and np.isfinite(hi):
            out.append(lo + 0.4 * (hi - lo))
        elif np.isfinite(lo):
            out.append(lo + 1.0)
        elif np.isfinite(hi):
            out.append(hi - 1.0)
        else:
            out.append(1.0)
    return np.array(out)


def check_jacobian_matches_finite_differences(model: Model) -> None:
    x, theta = inputs(model), typical_theta(model)
    analytic = np.asarray(model.jac(x, *theta), float)
    reference = ridders_jacobian(model.func, x, theta)
    assert analytic.shape == (N, model.n_params)
    scale = np.abs(reference).max(axis=0) + 1e-300
    np.testing.assert_allclose(analytic / scale, reference / scale, rtol=1e-6, atol=1e-8)


def _widths(x: np.ndarray, model: Model) -> tuple[float, float]:
    """(b_min, b_max) of the design (the plate widths a modulus rule is judged at)."""
    if "b_m" in model.columns:
        b = np.atleast_2d(x)[model.columns.index("b_m")]
        return float(b.min()), float(b.max())
    return INPUT_RANGES["b_m"]


def _broken(model: Model, theta: np.ndarray, widths: tuple[float, float]) -> list[str]:
    """The support rules (``Model.support``) that ``theta`` breaks."""
    values = {n: np.atleast_1d(v) for n, v in zip(model.param_names, theta, strict=True)}
    return [rule.label for rule in model.support if not np.all(rule.holds(values, widths))]


def check_start_values_inside_the_support(model: Model) -> None:
    """The record's start on data simulated from known parameters is finite, inside the
    record's support, and leads the least-squares fit back to the planted parameters."""
    if model.start is None:
        pytest.skip(f"{model.name} states no starting values (p0 is the caller's)")
    x, theta = inputs(model), typical_theta(model)
    y = np.asarray(model.func(x, *theta), float)
    start = np.asarray(model.start(x, y), float)
    assert start.shape == (model.n_params,) and np.isfinite(start).all(), start
    assert not _broken(model, start, _widths(x, model)), (
        start,
        _broken(model, start, _widths(x, model)),
    )
    fit = identify(model, x, y, start)
    np.testing.assert_allclose(fit.values, theta, rtol=1e-6, atol=1e-9 * np.abs(theta).max())


def _edges(prior) -> list[float]:
    """Points just inside each end of a prior's range (a closed end itself; ±1e12 for an
    open infinite end)."""
    lo, hi = float(getattr(prior, "lower", -np.inf)), float(getattr(prior, "upper", np.inf))
    closed = bool(getattr(prior, "closed_lower", False))
    inner_lo = -1e12 if not np.isfinite(lo) else lo if closed else lo + 1e-9 * max(1.0, abs(lo))
    inner_hi = 1e12 if not np.isfinite(hi) else hi - 1e-9 * max(1.0, abs(hi))
    return [inner_lo, inner_hi]


def check_priors_inside_the_support(model: Model) -> None:
    """No prior puts mass where a support rule on its parameter fails (a draw there would be
    refused after sampling: soilstats.bayes.support)."""
    theta = typical_theta(model)
    for k, name in enumerate(model.param_names):
        prior = model.prior_of.get(name)
        if prior is None:
            continue
        for value in _edges(prior):
            point = theta.copy()
            point[k] = value
            single = [r for r in model.support if getattr(r, "name", None) == name]
            values = {n: np.atleast_1d(v) for n, v in zip(model.param_names, point, strict=True)}
            for rule in single:
                assert np.all(rule.holds(values, INPUT_RANGES["b_m"])), (
                    f"{model.name}: the prior of {name} ({prior}) reaches {value:g}, where "
                    f"{rule.label}"
                )


def check_identifiability_hook(model: Model) -> None:
    """A design with one level of the input that separates the parameters leaves the
    Jacobian rank-deficient exactly when the record says it needs that input
    (``design_input``; for sinkage, ``min_plate_sizes`` > 1)."""
    assert model.min_plate_sizes >= 1
    if model.design_input is not None:
        assert model.design_input in model.columns, model.design_input
    theta = typical_theta(model)
    one = np.linalg.matrix_rank(np.asarray(model.jac(inputs(model, levels=1), *theta), float))
    full = np.linalg.matrix_rank(np.asarray(model.jac(inputs(model), *theta), float))
    assert full == model.n_params, f"{model.name}: not identifiable even on a full design"
    if one < model.n_params:
        assert model.design_input is not None, (
            f"{model.name}: one level of an input leaves it unidentifiable, and the record "
            "names no design_input to guard resamples and designs"
        )
        if model.kind == "sinkage":
            assert model.min_plate_sizes > 1


def check_round_trip_through_the_posterior(model: Model) -> None:
    if model.kind not in ("sinkage", "shear"):
        pytest.skip(f"{model.name}: a {model.kind or 'non-soil'} model has no posterior")
    theta = typical_theta(model)
    x = inputs(model)
    jac = np.asarray(model.jac(x, *theta), float)
    cov = np.linalg.inv(jac.T @ jac) * 1e-4
    plates = np.unique(x[0]) if "b_m" in model.columns else np.array([0.05])
    coords = sampling_coordinates(model, theta, cov, plates)
    back = np.ravel(coords.to_theta(coords.to_u(theta)))
    np.testing.assert_allclose(back, theta, rtol=1e-12)


#: Filled by the wheel layer: the round trip of a model's draws through the wheel model.
WHEEL_CHECKS: list[Callable[[Model], None]] = []

CHECKS: list[Callable[[Model], None]] = [
    check_jacobian_matches_finite_differences,
    check_start_values_inside_the_support,
    check_priors_inside_the_support,
    check_identifiability_hook,
    check_round_trip_through_the_posterior,
    *WHEEL_CHECKS,
]


def registered_checks() -> list:
    """(model name, check) for every registered model and every check, as pytest params."""
    return [
        pytest.param(name, check, id=f"{name}-{check.__name__.removeprefix('check_')}")
        for name in model_names()
        for check in CHECKS
    ]


@pytest.mark.parametrize(("name", "check"), registered_checks())
def test_every_registered_model(name, check):
    check(get_model(name))


def test_the_suite_covers_the_registry():
    assert len(registered_checks()) == len(model_names()) * len(CHECKS)
    assert {"bekker", "bernstein", "reece", "janosi", "mohr-coulomb"} <= set(model_names())


def test_the_checks_catch_a_wrong_record_and_see_a_new_one():
    """A record with a wrong Jacobian fails its check; a newly registered one is listed."""
    import dataclasses

    from soilstats.models import BERNSTEIN, register_model, unregister_model

    def half_jacobian(x, k, n):
        return 0.5 * np.asarray(BERNSTEIN.jac(x, k, n))

    wrong = dataclasses.replace(BERNSTEIN, name="bernstein-wrong-jac", jac=half_jacobian)
    with pytest.raises(AssertionError):
        check_jacobian_matches_finite_differences(wrong)
    register_model(wrong)
    try:
        assert any(p.values[0] == wrong.name for p in registered_checks())
    finally:
        unregister_model(wrong.name)
