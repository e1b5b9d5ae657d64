"""Test-level uncertainty: a cluster bootstrap over whole tests (Section 2.1's "random
characteristic" of the soil, which Eq. 4 does not see).

Eq. 4's covariance treats every sample as an independent observation.  The samples of one
test are not independent: each preparation gives the soil its own stiffness and exponent, so
the test, not the sample, is the unit of replication.  Resampling whole tests with replacement
and refitting gives the spread a new campaign of the same design would show: ``stderr_tests``.
With no test-to-test scatter it agrees with Eq. 4's σ; with scatter it is larger, often by a
factor of several on real data.

A resample draws T tests (with replacement) out of the T tests used; it is fitted by the same
weighted least squares, started from the full-data estimate, with each test's weights
multiplied by the square root of how often it was drawn (the same normal equations as
repeating its samples).  For the power laws all resamples are solved at once from per-test
sums (:mod:`soilstats.fitting.clustered`); a resample that kernel leaves is refitted exactly.
Mohr–Coulomb, linear in c and tan φ, is solved in closed form per resample (from per-test
sums too), as its fit is (Section 2.2).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from .._text import plural
from ..fitting.clustered import fit_clustered_resamples, fit_linear_resamples
from ..fitting.identify import RANK_CONDITION_LIMIT, eq4_covariance
from ..fitting.levenberg_marquardt import levenberg_marquardt
from ..fitting.separable import BATCH_ELEMENTS, fit_separable_batch, refine_exponent

if TYPE_CHECKING:
    from ..fitting.result import FitResult
    from ..models.base import Model
    from .pooling import PooledData

__all__ = ["TestBootstrap", "bootstrap_tests", "test_bootstrap"]

#: Below this many tests a bootstrap over tests says little (and resamples often hold a
#: single plate size); the fit says so instead of reporting a number.
MIN_TESTS = 5
#: Resamples of the test bootstrap a fit runs by default (``test_resamples="auto"``): the
#: test-level stderr's own sd is then within ~5 % (√(1/(2·200))), at ~10 ms a fit.
DEFAULT_RESAMPLES = 200

#: A resample whose tests span less than this share of the campaign's range of the design
#: input (plate size b for Bekker and Reece, normal pressure σ for shear) cannot separate
#: the parameters that input tells apart (kc from kφ, c from tan φ): it counts as failed.
#: Plate sizes are exact, so one plate size spans 0; normal pressures are measured, and the
#: tests of one nominal level differ by their noise, a few per cent of the range at most.
MIN_DESIGN_SPREAD = 0.1


@dataclass(frozen=True)
class TestBootstrap:
    """Estimates of every resample (rows) and what they say about the estimate's spread."""

    param_names: tuple[str, ...]
    estimate: np.ndarray  # the full-data estimate the resamples started from
    draws: np.ndarray  # (B, p) estimates of the resamples that converged
    n_resamples: int
    n_tests: int
    seed: int

    @property
    def n_failed(self) -> int:
        """Resamples whose fit did not converge or did not determine the parameters (left out
        of ``draws``; see :func:`_refit`)."""
        return self.n_resamples - len(self.draws)

    @property
    def stderr(self) -> pd.Series:
        """Test-level standard error of each parameter: the sd of the resampled estimates."""
        sd = (
            self.draws.std(axis=0, ddof=1)
            if len(self.draws) > 1
            else np.full(len(self.param_names), np.nan)
        )
        return pd.Series(sd, index=list(self.param_names), name="stderr_tests")

    @property
    def central_halfwidth(self) -> pd.Series:
        """Half the width of the central 68.3 % of the resampled estimates, per parameter:
        the sd for normal draws, but unmoved by a few extreme resamples (a robust scale to
        hold :attr:`stderr` against; ``bootstrap-unstable``)."""
        if len(self.draws) < 2:
            half = np.full(len(self.param_names), np.nan)
        else:
            low, high = np.percentile(self.draws, [15.865, 84.135], axis=0)
            half = (high - low) / 2.0
        return pd.Series(half, index=list(self.param_names), name="central_halfwidth")

    def sign_stability(self) -> pd.Series:
        """Share of resamples in which each parameter keeps the sign of the full estimate."""
        same = np.sign(self.draws) == np.sign(self.estimate)
        share = same.mean(axis=0) if len(self.draws) else np.full(len(self.param_names), np.nan)
        return pd.Series(share, index=list(self.param_names), name="sign_stability")


def bootstrap_tests(
    model: Model,
    x: ArrayLike,
    y: ArrayLike,
    weights: ArrayLike,
    test_index: ArrayLike,
    estimate: ArrayLike,
    *,
    n_resamples: int = 1000,
    seed: int = 0,
    design: ArrayLike | None = None,
) -> TestBootstrap:
    """Cluster bootstrap of a weighted LM fit over tests (see the module docstring).

    Parameters
    ----------
    model : Model
        The soil model of the fit (its analytic Jacobian and fast paths are used).
    x, y, weights : array_like
        The pooled data of the fit (as passed to :func:`soilstats.identify`).
    test_index : array_like of int
        For each sample, the position of its test (0 … T−1).
    estimate : array_like
        The full-data estimate; every resample starts there.
    n_resamples : int
        Number of resamples B (1000 gives the sd to about ±2 %).
    seed : int
        Seed of ``numpy.random.default_rng``: the same seed gives the same draws.
    design : array_like, optional
        Per sample, the input that separates the model's linear parameters (b [m] for
        Bekker, σ [Pa] for shear).  A resample whose tests span less than
        :data:`MIN_DESIGN_SPREAD` of the campaign's range of its per-test mean is not fitted
        and counts as failed (:attr:`TestBootstrap.n_failed`): it cannot determine them.
    """
    # Tests that contributed no sample are not part of the design: draw among the others.
    _, first_sample, test_index = np.unique(
        np.asarray(test_index, int), return_index=True, return_inverse=True
    )
    n_tests = int(test_index.max()) + 1 if test_index.size else 0
    rng = np.random.default_rng(seed)
    w = np.asarray(weights, float)
    y = np.asarray(y, float)
    start = np.asarray(estimate, float)
    picks = rng.integers(0, n_tests, (n_resamples, n_tests))  # row b: the tests drawn
    counts = np.zeros((n_resamples, n_tests), int)
    np.add.at(counts, (np.arange(n_resamples)[:, None], picks), 1)
    theta = np.full((n_resamples, len(model.param_names)), np.nan)
    done = np.zeros(n_resamples, bool)
    # Resamples that keep enough of the design to determine the parameters; only they are
    # fitted (the rest stay not done, i.e. failed).
    usable = _spans_design(design, test_index, n_tests, counts)

    def resample_weights(rows: list | np.ndarray) -> np.ndarray:  # w·√(times drawn), (rows, N)
        return w * np.sqrt(counts[rows][:, test_index])

    if model.linear_form is not None:
        # Linear after a change of variables: every resample's exact optimum in closed form;
        # one whose design does not determine the coefficients fails, as its LM would.
        design_matrix, to_params = model.linear_form(x)
        rows = np.flatnonzero(usable)
        beta, determined, _ = fit_linear_resamples(
            design_matrix, y, w, test_index, counts[rows], max_condition=RANK_CONDITION_LIMIT
        )
        theta[rows[determined]] = to_params(beta[determined])
        done[rows[determined]] = True
    elif model.separable is not None:
        # Power laws: every resample's exact optimum at once (variable projection, batched).
        basis, log_z = model.separable(x, np.ones_like(w))
        g = basis(0.0)  # (q, N) the basis without z^n
        g_test = g[:, first_sample]  # at each test's first sample
        if np.array_equal(g, g_test[:, test_index]):
            # The basis is constant within each test (1/b and 1): per-test sums suffice.
            rows = np.flatnonzero(usable)
            theta[rows], done[rows] = fit_clustered_resamples(
                g_test.T, log_z, y, w, test_index, counts[rows], start[-1]
            )
        rest = np.flatnonzero(usable & ~done)  # the basis varies within a test, or a row strayed
        block = max(1, BATCH_ELEMENTS // max(w.size, 1))
        for first in range(0, rest.size, block):
            rows = rest[first : first + block]
            theta[rows], done[rows] = fit_separable_batch(
                g, log_z, y, resample_weights(rows), start[-1]
            )
    # Other models, and what the power-law batch left; the closed form leaves nothing an LM
    # could determine.
    left = np.flatnonzero(usable & ~done) if model.linear_form is None else ()
    for i in left:
        refit = _refit(model, x, y, resample_weights([i])[0], start)
        if refit is not None:
            theta[i], done[i] = refit, True
    draws = theta[done]
    p = len(model.param_names)
    return TestBootstrap(
        param_names=tuple(model.param_names),
        estimate=np.asarray(estimate, float),
        draws=np.array(draws).reshape(-1, p),
        n_resamples=n_resamples,
        n_tests=n_tests,
        seed=seed,
    )


def _spans_design(
    design: ArrayLike | None, test_index: np.ndarray, n_tests: int, counts: np.ndarray
) -> np.ndarray:
    """(B,) whether each resample's tests span at least :data:`MIN_DESIGN_SPREAD` of the
    campaign's range of the per-test mean of ``design`` (all True without a design)."""
    usable = np.ones(counts.shape[0], bool)
    if design is None:
        return usable
    design = np.asarray(design, float)
    per_test = np.bincount(test_index, weights=design, minlength=n_tests) / np.bincount(
        test_index, minlength=n_tests
    )
    full = float(np.ptp(per_test)) if per_test.size else 0.0
    if not full > 0:  # one level in the whole campaign: no resample can do better
        return usable
    drawn = counts > 0
    highest = np.where(drawn, per_test, -np.inf).max(axis=1)
    lowest = np.where(drawn, per_test, np.inf).min(axis=1)
    return highest - lowest >= MIN_DESIGN_SPREAD * full


def test_bootstrap(
    model: Model,
    x: ArrayLike,
    pooled: PooledData,
    fit: FitResult,
    n_resamples: int | Literal["auto"],
    seed: int,
    notes: list,
) -> TestBootstrap | None:
    """The bootstrap of a pooled fit, or None (0 resamples, or too few tests: said in
    ``notes`` when resamples were asked for).  Resamples start from the fit's estimate.

    ``n_resamples="auto"``: :data:`DEFAULT_RESAMPLES` where the fit rests on
    :data:`MIN_TESTS` tests or more — its stderr is then the test-level one
    (docs/conventions.md) — and none below (the fit's ``few-tests`` flag says why)."""
    n_tests = np.unique(pooled.test_index).size
    if n_resamples == "auto":
        n_resamples = DEFAULT_RESAMPLES if n_tests >= MIN_TESTS else 0
    if n_resamples <= 0:
        return None
    if n_tests < MIN_TESTS:
        notes.append(
            f"no test-level stderr: {plural(n_tests, 'test')} {'is' if n_tests == 1 else 'are'} "
            f"too few to resample (needs {MIN_TESTS})"
        )
        return None
    return bootstrap_tests(
        model,
        x,
        pooled.y,
        pooled.weights,
        pooled.test_index,
        fit.values,
        n_resamples=n_resamples,
        seed=seed,
        design=pooled.x.get(model.design_input or ""),  # the record's (Model.design_input)
    )


def _refit(
    model: Model, x: ArrayLike, y: np.ndarray, w: np.ndarray, start: np.ndarray
) -> np.ndarray | None:
    """The weighted LM optimum of one resample (the identification's own path: variable
    projection to the exponent, then LM), or None when it does not converge or its end point
    does not determine the parameters.

    The second is :func:`~soilstats.fitting.identify`'s rank test (cond(J D⁻¹) above
    ``RANK_CONDITION_LIMIT``): a resample that drew tests of one plate size (Bekker) or one
    normal pressure (Mohr–Coulomb, Janosi) cannot separate kc from kφ (c from tan φ), and the
    LM stops somewhere along the undetermined direction, near its start.  Kept as a draw,
    such a resample shrank or inflated ``stderr_tests`` (one design: kc's sd 2 988 for 3 603
    without them; another: c's 98.5 Pa for 14.5 Pa) and hid the failures from
    ``bootstrap-unstable``."""
    wy = w * y
    f_weighted, jacobian = model.evaluators(x, w)
    with np.errstate(all="ignore"):
        if model.separable is not None:
            basis, log_z = model.separable(x, w)
            start, _ = refine_exponent(basis, log_z, wy, start, ftol=1e-9)
        out = levenberg_marquardt(lambda t: wy - f_weighted(t), jacobian, start, ftol=1e-15)
    if not out.converged or not np.all(np.isfinite(out.params)):
        return None
    cond, _ = eq4_covariance(out.jacobian, 2.0 * out.cost, w.size, out.gram, out.scaled)
    if not cond <= RANK_CONDITION_LIMIT:
        return None
    return out.params
