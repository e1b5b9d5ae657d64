"""Test-level σ of discovery's fitted models: the cluster-robust covariance over tests.

Eq. 4's covariance (the ``± σ`` of every fit) treats each sample as independent; the
samples of one test are not — each preparation gives the soil a stiffness and exponent of
its own (the paper's random characteristic, Section 2.1), so the test is the unit of
replication.  ``soilstats identify`` measures that by a cluster bootstrap over tests
(``stderr_tests``, 200 refits per fit; :mod:`soilstats.identification.bootstrap`); too
slow for discovery, which fits many models per group.  Here the same quantity is taken in
its linearised form, the cluster-robust ("sandwich") covariance with tests as clusters,

    Cov_tests(θ̂) = m/(m − 1) · Σ_g IF_g IF_gᵀ,   IF_g = (JᵀJ)⁻¹ J_gᵀ r_g,

(J, r: the weighted Jacobian and residuals at the estimate; g over the tests; IF_g is test
g's influence on θ̂, so m, the number of tests with an influence on the parameter, is the
number of tests that inform it).  It costs one Jacobian of the fitted model — no refit —
and equals the bootstrap's variance to first order.

What it cannot give: a test-level σ of a parameter that rests on one test alone (a level of
one test: its factor is that test's own stiffness, with nothing to tell its scatter by).
Those are NaN, and the single-test caveat of the finding names them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..identification.bootstrap import MIN_TESTS
from ..identification.result import DISAGREEMENT

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from ..fitting.result import FitResult
    from .data import Group
    from .extensions import Fitted

__all__ = ["TestLevel", "eq4_reason", "quoted_sigma", "scatter_caveat", "test_level"]

# A test's influence on a parameter below this share of the largest test's is rounding
# (the score of a test that alone sets a parameter is zero at the optimum, up to the fit's
# tolerance), not information.
_INFLUENCE_TOL = 1e-6
# An eigenvalue of the other tests' scaled information matrix below this: a direction
# they leave undetermined, which the one test left out sets alone.
_NULL_TOL = 1e-9


@dataclass(frozen=True, eq=False)
class TestLevel:
    """Test-level σ of one fit's parameters (arrays in the fit's parameter order).

    Attributes
    ----------
    stderr : numpy.ndarray
        Cluster-robust σ over tests, in the parameters' units; NaN where a parameter rests
        on one test alone.
    ratio : numpy.ndarray
        ``stderr`` / Eq. 4's σ (dimensionless).
    informed_by : numpy.ndarray of int
        Tests with an influence on each parameter (m of the module docstring).
    n_tests : int
        Tests the fit was made on.
    """

    __test__ = False  # not a pytest class, despite its name

    stderr: np.ndarray
    ratio: np.ndarray
    informed_by: np.ndarray
    n_tests: int

    def flagged(self) -> np.ndarray:
        """Parameters whose test-level σ exceeds Eq. 4's by more than ``DISAGREEMENT`` (2×),
        judged only where at least ``MIN_TESTS`` (5) tests inform them — ``identify``'s
        ``test-scatter`` rule; with fewer the sandwich is too noisy to judge by."""
        ok = np.isfinite(self.ratio) & (self.informed_by >= MIN_TESTS)
        return ok & (np.where(ok, self.ratio, 0.0) > DISAGREEMENT)


def _weighted_rows(
    fitted: Fitted, group: Group, rows: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """(p, N) rows of the weighted Jacobian at the estimate and the owner test of each
    sample, for the extensions whose family is at hand (all but Reece's)."""
    inputs = getattr(fitted.extension, "_inputs", None)
    if inputs is None:
        return None
    mask, _, family = inputs(group, rows, fitted.state)
    return family.rows(np.asarray(fitted.result.values, float), group.w[mask]), group.owner[mask]


def test_level(fitted: Fitted, group: Group, rows: ArrayLike) -> TestLevel | None:
    """The cluster-robust test-level σ of ``fitted`` (a :class:`~.extensions.Fitted` made on
    the tests ``rows`` of ``group``); None where it cannot be formed (no Eq. 4 covariance,
    fewer than 2 tests, a model without its family: Reece)."""
    fit = fitted.result
    rows = np.asarray(rows, int)
    cov = np.asarray(fit.covariance, float)
    if rows.size < 2 or fit.dof <= 0 or not np.isfinite(cov).all() or fit.residuals is None:
        return None
    got = _weighted_rows(fitted, group, rows)
    if got is None:
        return None
    jac, owner = got
    resid = np.asarray(fit.residuals, float)
    if jac.shape[1] != resid.size:
        return None
    tests, idx = np.unique(owner, return_inverse=True)
    n_par, n_tests = jac.shape[0], tests.size
    scores = np.stack([np.bincount(idx, jac[j] * resid, n_tests) for j in range(n_par)], 1)
    bread = cov / (fit.rss / fit.dof)  # (JᵀJ)⁻¹, as the fit inverted it (scaled)
    influence = scores @ bread  # (tests, p)
    big = np.abs(influence).max(axis=0)
    informed = (np.abs(influence) > _INFLUENCE_TOL * big).sum(axis=0)
    m = informed.astype(float)
    with np.errstate(divide="ignore", invalid="ignore"):
        var = np.where(m > 1, m / (m - 1), np.nan) * (influence**2).sum(axis=0)
    stderr = np.sqrt(var)
    stderr[_resting_on_one(jac, idx, n_tests)] = np.nan
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = stderr / np.asarray(fit.stderr_values, float)
    return TestLevel(stderr, ratio, informed, int(n_tests))


def _resting_on_one(jac: np.ndarray, idx: np.ndarray, n_tests: int) -> np.ndarray:
    """Parameters that one test alone determines: without it, the other tests leave them
    undetermined (a null direction of their information matrix involves them)."""
    n_par = jac.shape[0]
    gram = jac @ jac.T
    scale = np.sqrt(np.diag(gram))
    if not (scale > 0).all():
        return np.ones(n_par, bool)
    # Each test's own share of the information, by one bincount per pair of parameters: a
    # mask over the samples per test would cost tests × samples (6.6 s of discovery at
    # 10 000 tests).
    own = np.empty((n_tests, n_par, n_par))
    for a, b in zip(*np.triu_indices(n_par), strict=True):
        own[:, a, b] = own[:, b, a] = np.bincount(idx, jac[a] * jac[b], n_tests)
    eig, vecs = np.linalg.eigh((gram - own) / np.outer(scale, scale))  # one per test left out
    null = eig < _NULL_TOL * eig[:, -1:]  # (tests, directions)
    return ((np.abs(vecs) > 0.1) & null[:, None, :]).any(axis=(0, 2))


def quoted_sigma(
    fit: FitResult, level: TestLevel | None
) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The σ to print of each parameter of ``fit`` (issue #36, docs/conventions.md):
    ``(stderr, stderr_eq4, stderr_level)`` per parameter, in the fit's order.

    ``stderr`` is the test-level σ (``level.stderr``) where five tests or more inform the
    parameter (``MIN_TESTS``, as identify decides per fit) and the σ could be formed —
    ``stderr_level`` ``"tests"`` — and Eq. 4's σ otherwise (``"eq4"``: fewer than five tests
    inform it, one test alone sets it, or no test-level σ exists for the model, e.g.
    Reece's): there the scatter between tests could not be measured."""
    eq4 = np.asarray(fit.stderr_values, float)
    tests = np.zeros(eq4.size, bool)
    if level is not None:
        st = np.asarray(level.stderr, float)
        tests = np.isfinite(st) & (np.asarray(level.informed_by) >= MIN_TESTS)
    stderr = np.where(tests, level.stderr if level is not None else eq4, eq4)
    return stderr, eq4, ["tests" if t else "eq4" for t in tests]


def eq4_reason(level: TestLevel | None, j: int) -> str:
    """Why parameter ``j`` carries Eq. 4's σ (``quoted_sigma`` gave ``"eq4"``), in words."""
    if level is None:
        return "no test-level σ for this model"
    if not np.isfinite(level.stderr[j]):
        return "one test alone sets it"
    return f"{level.informed_by[j]} tests inform it, fewer than five"


def scatter_caveat(fit: FitResult, level: TestLevel | None) -> str | None:
    """The ``test-scatter`` caveat of a fit whose tests scatter more than Eq. 4's σ says
    (None when no parameter is flagged)."""
    if level is None:
        return None
    hit = np.flatnonzero(level.flagged())
    if hit.size == 0:
        return None
    parts = [
        f"{fit.param_names[j]} {level.stderr[j]:.3g} = {level.ratio[j]:.2g}× Eq. 4's "
        f"{fit.stderr_values[j]:.3g} ({level.informed_by[j]} tests)"
        for j in hit
    ]
    return (
        "TEST-SCATTER: the tests scatter more than their samples say, so Eq. 4's ± σ is too "
        "small an error bar; quote the test-level σ (cluster-robust over tests, marked * in "
        "the table): "
        + "; ".join(parts)
        + ". `soilstats identify` gives its bootstrap counterpart, stderr_tests, per condition"
    )
