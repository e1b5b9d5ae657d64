"""Prior sensitivity of a posterior by power-scaling, without sampling again.

Kallioinen, Paananen, Bürkner & Vehtari (2023), "Detecting and diagnosing prior and likelihood
sensitivity with power-scaling", Statistics and Computing 34:57 (the method of the R package
``priorsense``).  Scaling the prior p(θ) to p(θ)^α changes the posterior by the importance
weights p(θ)^(α−1) on the existing draws; they are Pareto-smoothed (:func:`arviz.psislw`,
whose shape k says whether the reweighting can be trusted: k ≤ 0.7).  For each quantity,
the cumulative Jensen–Shannon distance (CJS, Nguyen & Vreeken 2015) between its weighted and
unweighted empirical CDFs at α = 0.99 and α = 1.01 is divided by 2·log2(1.01): the
derivative of the distance with respect to log2 α.  Above :data:`THRESHOLD` (0.05, the
paper's) the prior is *influential*: a posterior that moves when the prior is made a little
stronger or weaker rests on the prior, not on the data alone.

Only priors that are not flat can be detected this way (a flat density to any power is flat):
the pooled models' default priors (:mod:`.priors`) are flat on their support and give 0; the
population model's defaults — flat in the log of the measured scales, half-Cauchy scatter
scales, Beta(2, 2) correlation — are not, and are the ones this check is for.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from ..errors import DefaultWarning, InputError
from ..models.priors import Prior
from ._arviz import az

__all__ = [
    "DELTA",
    "K_MAX",
    "THRESHOLD",
    "cjs_distance",
    "influential_warning",
    "pooled_sensitivity",
    "power_scaling_sensitivity",
    "sensitivity_table",
    "warn_influential",
]

#: Power-scaling step: α = 1 − DELTA and 1 + DELTA (priorsense's 0.99 and 1.01).
DELTA = 0.01
#: Sensitivity above which a prior is influential (Kallioinen et al. 2023, Section 4).
THRESHOLD = 0.05
#: Pareto k above which the reweighted draws are not trusted (Vehtari et al. 2024).
K_MAX = 0.7


def _cjs(x: np.ndarray, w: np.ndarray) -> float:
    """CJS distance between the ECDF of sorted ``x`` (equal weights) and its reweighting by
    ``w`` (normalised), both on the bins between consecutive draws, scaled by its bound."""
    width = np.diff(x)
    p = np.arange(1, x.size) / x.size
    q = np.cumsum(w)[:-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        pq = np.nansum(width * p * (np.log2(p) - np.log2(0.5 * (p + q))))
        qp = np.nansum(width * q * (np.log2(q) - np.log2(0.5 * (p + q))))
    p_int, q_int = float(np.sum(width * p)), float(np.sum(width * q))
    pq += 0.5 / np.log(2) * (q_int - p_int)
    qp += 0.5 / np.log(2) * (p_int - q_int)
    bound = p_int + q_int
    return float(np.sqrt(max(pq + qp, 0.0) / bound)) if bound > 0 else 0.0


def cjs_distance(x: np.ndarray, weights: np.ndarray) -> float:
    """Cumulative Jensen–Shannon distance between the draws ``x`` and the same draws with
    ``weights`` (any positive scale): the larger of the distances of x and of −x, so that
    it does not depend on the sign convention of the quantity; 0 for equal weights."""
    x = np.asarray(x, float).ravel()
    w = np.asarray(weights, float).ravel()
    w = w / w.sum()
    order = np.argsort(x, kind="stable")
    up = _cjs(x[order], w[order])
    down = _cjs(-x[order][::-1], w[order][::-1])
    return max(up, down)


def power_scaling_sensitivity(
    draws: Mapping[str, np.ndarray], log_prior: np.ndarray, *, delta: float = DELTA
) -> tuple[dict[str, float], float]:
    """``({quantity: sensitivity}, Pareto k)`` of the posterior ``draws`` (each flattened
    over chains; one value per draw) to power-scaling the prior whose log-density at each
    draw is ``log_prior`` (up to a constant).

    The sensitivity is (CJS(α = 1 − δ) + CJS(α = 1 + δ)) / (2 log2(1 + δ)); the Pareto k is
    the larger of the two smoothings'.  A prior constant on the draws (flat) gives 0 and k
    NaN (nothing to reweight).
    """
    lp = np.asarray(log_prior, float).ravel()
    if not np.all(np.isfinite(lp)):
        # every posterior draw lies in the prior's support: a non-finite value is a bug
        raise InputError("log_prior must be finite at every posterior draw")
    if np.ptp(lp) == 0:
        return {name: 0.0 for name in draws}, float("nan")
    out = dict.fromkeys(draws, 0.0)
    k_max = -np.inf
    for alpha in (1 - delta, 1 + delta):
        lw, k = az.psislw((alpha - 1) * (lp - lp.max()))
        k_max = max(k_max, float(k))
        w = np.exp(lw - lw.max())
        for name, x in draws.items():
            out[name] += cjs_distance(np.asarray(x).ravel(), w)
    scale = 2 * np.log2(1 + delta)
    return {name: v / scale for name, v in out.items()}, k_max


def _scale(x: np.ndarray) -> np.ndarray:
    """The draws of a quantity on the scale its sensitivity is judged on: the logarithm of a
    quantity positive at every draw (a modulus, a scatter sd, K), the draws otherwise.  The
    CJS distance integrates over the quantity's axis, so it is not invariant to a monotone
    transform: on the raw scale, the long right tail of a modulus spanning decades (Bernstein
    k, the pressure at 1 m) dominates it (GRC-1's new-preparation k: 0.15 raw, 0.02 in ln),
    while the population model is defined in the logs of its scales."""
    x = np.asarray(x, float).ravel()
    return np.log(x) if np.all(x > 0) else x


def sensitivity_table(
    draws: Mapping[str, np.ndarray],
    log_default: np.ndarray,
    log_given: np.ndarray | None,
    given: tuple[str, ...] = (),
) -> pd.DataFrame:
    """One row per quantity of ``draws``: its sensitivity to the *default* priors
    (``log_default`` per draw) and, where the user gave some (``given``, ``log_given``), to
    those; ``influential`` marks a default-prior sensitivity above :data:`THRESHOLD` with
    trusted weights (Pareto k ≤ :data:`K_MAX`).  A quantity positive at every draw is judged
    in its logarithm (:func:`_scale`)."""
    draws = {q: _scale(x) for q, x in draws.items()}
    default, k_default = power_scaling_sensitivity(draws, log_default)
    stated, k_stated = (
        power_scaling_sensitivity(draws, log_given)
        if log_given is not None and given
        else ({n: float("nan") for n in draws}, float("nan"))
    )
    table = pd.DataFrame(
        {
            "quantity": list(draws),
            "default_prior_sensitivity": [default[n] for n in draws],
            "default_prior_pareto_k": k_default,
            "given_prior_sensitivity": [stated[n] for n in draws],
            "given_prior_pareto_k": k_stated,
        }
    )
    trusted = ~(table["default_prior_pareto_k"] > K_MAX)
    table["influential"] = (table["default_prior_sensitivity"] > THRESHOLD) & trusted
    table.attrs["given"] = ", ".join(given)
    return table


def pooled_sensitivity(
    posterior: Any, param_names: Sequence[str], priors: Sequence[Prior], given: Iterable[str]
) -> pd.DataFrame:
    """:func:`sensitivity_table` of a pooled posterior (an ArviZ ``posterior`` group): the
    default priors are those of the parameters not in ``given`` and the Jeffreys prior
    1/σ_w of the noise scale; the given ones are the user's (``priors=`` of the sampler)."""
    chosen = set(given)
    draws = {n: np.asarray(posterior[n]).ravel() for n in param_names}
    log_default = np.zeros(next(iter(draws.values())).size)
    if "sigma_w" in posterior:
        draws["sigma_w"] = np.asarray(posterior["sigma_w"]).ravel()
        log_default = -np.log(draws["sigma_w"])
    log_given = np.zeros_like(log_default)
    for name, prior in zip(param_names, priors, strict=True):
        if name in chosen:
            log_given = log_given + prior.logpdf(draws[name])
        else:
            log_default = log_default + prior.logpdf(draws[name])
    return sensitivity_table(
        draws, log_default, log_given, tuple(n for n in param_names if n in chosen)
    )


def influential_warning(model_name: str, table: pd.DataFrame | None) -> str | None:
    """The warning for the quantities of ``table`` whose default priors are influential,
    or None: what moved, by how much, and what to do."""
    if table is None or table.empty or not table["influential"].any():
        return None
    rows = table[table["influential"]].sort_values("default_prior_sensitivity", ascending=False)
    listed = ", ".join(
        f"{q} ({s:.2f})"
        for q, s in zip(rows["quantity"], rows["default_prior_sensitivity"], strict=True)
    )
    return (
        f"the default priors of the {model_name} posterior are influential: power-scaling "
        f"sensitivity above {THRESHOLD:g} for {listed} — these draws rest on priors nobody "
        "stated, not on the tests alone; state a prior you can defend for the soil "
        "parameters (--prior NAME=SPEC) or add tests (the priors of the scatter between "
        "preparations are fixed: only more tests help; docs/posterior.md, 'Prior sensitivity')"
    )


def warn_influential(model_name: str, table: pd.DataFrame | None) -> None:
    """:func:`influential_warning` as a :class:`~soilstats.errors.DefaultWarning`."""
    text = influential_warning(model_name, table)
    if text is not None:
        warnings.warn(text, DefaultWarning, stacklevel=3)
