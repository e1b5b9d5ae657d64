"""Per-test identification: one parameter set per test, as the response of setup studies.

A pooled fit (Section 2) answers "what are this soil's parameters?"; a setup study asks
"does this factor move them, beyond the test-to-test scatter?", and needs one value per test
(one repetition = one observation of the ANOVA).  What one test can identify:

* **sinkage** — one plate size, so Bernstein p = k·z^n (Eq. 8) with k = kc/b + kφ; the
  size terms of Bekker (Eq. 7) need several plates and stay a pooled question.
* **shear** — one normal pressure, so τ = τ_max·(1 − e^{−j/K}) (Eq. 13 with τ_max =
  c + σ tan φ), plus the steady-state level τ_ss and the mean normal pressure σ of the test
  (the data points of Eq. 15 / Figs. 11–14); c and φ come from τ_ss against σ.

Every selected test gets a row; a test whose fit fails keeps its row with ``converged`` False,
NaN parameters and the reason in ``message`` — and a warning counts them.  Nothing is dropped.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from itertools import pairwise
from typing import TYPE_CHECKING, Literal, cast

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from ..errors import CampaignError, ConvergenceError, ConvergenceWarning, InputError
from ..fitting.identify import identify
from ..fitting.result import FitResult
from ..kinds import TEST_KINDS
from ..models import BERNSTEIN, SHEAR_CURVE
from ..parallel import effective_jobs, parallel_map
from ..quality import screened
from .centring import centred
from .pooling import kept_samples
from .steady_state import steady_state

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..campaign.tables import Criterion

__all__ = ["fit_per_test", "not_converged_message"]


def fit_per_test(
    campaign: Campaign,
    kind: Literal["sinkage", "shear"] = "sinkage",
    *,
    points_per_test: int | None = 100,
    progress: bool = False,
    jobs: int | None = 1,
    **selection: Criterion,
) -> pd.DataFrame:
    """Fit every selected test on its own; one row per test with its test-log columns.

    Parameters
    ----------
    campaign : Campaign
    kind : {"sinkage", "shear"}
    points_per_test : int or None
        Sinkage: samples nearest to equally spaced sinkages (Section 2.1), as in
        :func:`soilstats.fit_sinkage`.
    progress : bool
        Show a tqdm progress bar.
    jobs : int, default 1
        Worker processes over the tests (:func:`soilstats.parallel.parallel_map`; −1 every
        core).  Each test's fit depends on its own samples only, so the rows are identical
        for any ``jobs``.
    **selection
        Test-log filters (any number of soils may remain: nothing is pooled).

    Returns
    -------
    pandas.DataFrame
        The test log (with derived columns) plus, for sinkage, ``k`` [N/m^(n+2)], ``k_stderr``,
        ``n``, ``n_stderr``, ``z_max_m``, ``p_max_Pa``; for shear, ``tau_max`` [Pa],
        ``tau_max_stderr``, ``K`` [m], ``K_stderr``, ``sigma_mean_Pa``, ``tau_ss_Pa`` (NaN when the
        test never reaches a steady state), ``steady``; and for both ``epsilon`` (Eq. 2 on
        the 1/max-weighted data), ``nobs``, ``converged``, ``message``.
    """
    if kind not in TEST_KINDS:
        raise InputError(f"kind must be 'sinkage' or 'shear', got {kind!r}")
    chosen = screened(campaign, "clean", **selection)
    tests = chosen.tests[chosen.tests["kind"] == kind].reset_index(drop=True)
    if tests.empty:
        crit = ", ".join(f"{k}={v!r}" for k, v in selection.items()) or "no selection"
        raise CampaignError(
            f"no {kind} tests match ({crit})", file=campaign.file_name("tests"), column="kind"
        )
    samples = chosen.sinkage if kind == "sinkage" else chosen.shear
    by_test = samples.groupby("test_id", sort=False).indices
    fit_one = _fit_sinkage_test if kind == "sinkage" else _fit_shear_test
    if kind == "sinkage":
        columns = {"z": samples["z_m"], "y": samples["pressure_Pa"]}
    else:
        columns = {"z": samples["j_m"], "y": samples["tau_Pa"], "sigma": samples["sigma_Pa"]}
    arrays = {key: col.to_numpy(float) for key, col in columns.items()}
    ids = tests["test_id"].astype(str).to_numpy()
    empty = np.array([], int)
    items = [(tid, {k: v[by_test.get(tid, empty)] for k, v in arrays.items()}) for tid in ids]
    if effective_jobs(jobs) > 1 and len(items) > 1:
        # Workers take contiguous chunks of tests (eight per worker, so that uneven fits even
        # out), each with its own samples only; the rows come back in the tests' order.
        n_chunks = min(len(items), 8 * effective_jobs(jobs))
        bounds = np.linspace(0, len(items), n_chunks + 1).astype(int)
        chunks = [(kind, items[a:b], points_per_test) for a, b in pairwise(bounds)]
        done = parallel_map(
            _fit_chunk, chunks, jobs=jobs, progress=progress, desc=f"per-test {kind} fits"
        )
        rows = [row for chunk in done for row in chunk]
    else:
        if progress:
            from tqdm.auto import tqdm  # deferred: tqdm (a progress bar)

            items = tqdm(items, desc=f"per-test {kind} fits", unit="test")
        rows = [fit_one(tid, data, points_per_test) for tid, data in items]
    fits = pd.DataFrame(rows)
    message = not_converged_message(fits, kind)
    if message:
        warnings.warn(message, ConvergenceWarning, stacklevel=2)
    return tests.merge(fits, on="test_id", how="left", validate="one_to_one")


def not_converged_message(table: pd.DataFrame, kind: str) -> str | None:
    """What :func:`fit_per_test` warns of the rows of ``table`` (its result, or part of it)
    whose fit did not converge; None when every fit converged."""
    failed = table.loc[~table["converged"].astype(bool), "test_id"].astype(str).tolist()
    if not failed:
        return None
    return (
        f"{len(failed)} of {len(table)} per-test {kind} fits did not converge "
        f"({', '.join(failed[:8])}{', …' if len(failed) > 8 else ''}); their rows hold NaN "
        "and the reason in 'message'"
    )


def _fit_chunk(item: tuple[str, list[tuple[str, dict]], int | None]) -> list[dict]:
    """The rows of a chunk of tests, ``(kind, [(test_id, samples)], points_per_test)``, in
    a worker."""
    kind, tests, points_per_test = item
    fit_one = _fit_sinkage_test if kind == "sinkage" else _fit_shear_test
    return [fit_one(tid, data, points_per_test) for tid, data in tests]


def _fit_sinkage_test(tid: str, data: dict, points_per_test: int | None) -> dict:
    kept = kept_samples(data["z"], data["y"], "sinkage", points_per_test=points_per_test)
    z, p = data["z"][kept.index], data["y"][kept.index]
    row = {"test_id": tid, "nobs": int(z.size), "z_max_m": np.nan, "p_max_Pa": np.nan}
    if kept.problem is not None:
        return _failed(row, ("k", "n"), kept.problem)
    row.update(z_max_m=float(z.max()), p_max_Pa=float(p.max()))
    try:
        fit = fit_bernstein_test(z, p, np.full(z.size, kept.weight), name=f"bernstein {tid}")
    except TEST_FIT_ERRORS as exc:
        return _failed(row, ("k", "n"), str(exc))
    return _fitted(row, fit)


#: What a single test's fit may raise: the test is then reported as failed, never dropped.
TEST_FIT_ERRORS = (ConvergenceError, ValueError, np.linalg.LinAlgError)


def fit_bernstein_test(
    z: np.ndarray, p: np.ndarray, weights: ArrayLike | None, *, name: str = "bernstein"
) -> FitResult:
    """Bernstein (Eq. 8) on one test's kept samples: z [m], p [Pa], per-sample weights.

    The one per-test sinkage fit of soilstats (per-test responses, discovery, the population
    posterior).  Starts from Wong's estimate; raises one of :data:`TEST_FIT_ERRORS`.
    """
    p0 = cast(Callable, BERNSTEIN.start)(z, p)  # Bernstein has its starting values
    return centred(identify(BERNSTEIN, z, p, p0, weights=weights, name=name), z)


def fit_shear_test(
    j: np.ndarray, tau: np.ndarray, weights: ArrayLike | None, *, name: str = "shear"
) -> FitResult:
    """Eq. 13 at one normal pressure, τ = τ_max·(1 − e^(−j/K)), on one test's samples.

    j [m], τ [Pa], per-sample weights.  The one per-test shear fit of soilstats (per-test
    responses, the population posterior).  Raises one of :data:`TEST_FIT_ERRORS`.
    """
    # Plateau from the top decile, K where τ reaches 63 %.
    p0 = cast(Callable, SHEAR_CURVE.start)(j, tau)
    return identify(SHEAR_CURVE, j, tau, p0, weights=weights, name=name)


def _fit_shear_test(tid: str, data: dict, points_per_test: int | None) -> dict:
    j, tau, sigma = data["z"], data["y"], data["sigma"]
    row = {
        "test_id": tid,
        "sigma_mean_Pa": float(np.mean(sigma)) if sigma.size else np.nan,
        "tau_ss_Pa": np.nan,
        "steady": False,
    }
    if j.size:
        ss = steady_state(j, tau)
        row.update(steady=bool(ss.steady), tau_ss_Pa=float(ss.tau_level) if ss.steady else np.nan)
    kept = kept_samples(j, tau, "shear", points_per_test=None)  # whole record, as fit_shear
    j, tau = j[kept.index], tau[kept.index]
    row["nobs"] = int(j.size)
    if kept.problem is not None:
        return _failed(row, ("tau_max", "K"), kept.problem)
    try:
        fit = fit_shear_test(j, tau, np.full(j.size, kept.weight), name=f"shear {tid}")
    except TEST_FIT_ERRORS as exc:
        return _failed(row, ("tau_max", "K"), str(exc))
    return _fitted(row, fit)


def _fitted(row: dict, fit: FitResult) -> dict:
    for name, value, sd in zip(fit.param_names, fit.values, fit.stderr_values, strict=True):
        row[name], row[f"{name}_stderr"] = float(value), float(sd)
    flags = [f.code for f in fit.flags]
    row.update(epsilon=fit.epsilon, converged=bool(fit.converged), message="; ".join(flags) or "ok")
    return row


def _failed(row: dict, names: tuple[str, ...], reason: str) -> dict:
    for name in names:
        row[name] = row[f"{name}_stderr"] = np.nan
    row.update(epsilon=np.nan, converged=False, message=reason)
    return row
