"""Silence is not evidence: the smallest effect each test could have found.

For a candidate that was *not* found, discovery states the minimum detectable effect (MDE)
at the campaign's design: the effect that the F-test of :mod:`.diagnose` would detect with
probability ``power`` (default 0.8) at the strictest level Holm's method applies, α/m (m =
tests in the family — a lone true effect among nulls must beat α/m to be named).

Under an effect δ the F statistic follows a noncentral F(df1, df2, λ) with
λ = δ²·‖r‖²/σ², where r is the effect's pattern over the tests after the strata (and any
main effects) are taken out and σ the residual standard deviation of the response.  The
MDE solves P(F(df1, df2, λ) > F_crit) = power for λ and returns δ = σ·√(λ/‖r‖²).  The
patterns (:func:`soilstats.discovery.ftests.strata_test`):

* levels — one level (or, for an interaction, one cell against the additive model)
  shifted by δ against the others; the hardest level to detect (fewest tests), so that
  *any* level shifted by δ or more would have been found;
* a drift within blocks — a change of δ across one block's own range of a time/order
  candidate, against the common trend (the hardest block);
* trend — a change of δ across the observed range of the candidate (on ln x when x spans
  more than a factor four, except for time/order candidates, as they are tested).

The one-cell test of an interaction and the test of a drift within blocks take the largest
of K one-degree-of-freedom tests, Bonferroni-adjusted (:func:`.ftests.interaction_test`,
:func:`.ftests.within_blocks_test`): their MDE is at α/(m·K) with one degree of freedom.

δ is in the response's units: ln of pressure (sinkage ``level``) or plateau stress (shear
``level``), the exponent n (``shape``), ln K (``K``).  :func:`describe` turns it into a
sentence with physical units.

**Capped to what the data can express.**  An MDE larger than the observed range of the
response over the tests the candidate was tested on (max − min of the per-test responses)
says nothing: the tests themselves never differed that much, so no effect the data show
could have been that large.  Such a statement reads "not testable here" with the range,
and its ``mde`` is null in JSON (``mde_uncapped`` keeps the number): on the CMU plates the
trend in ``test_number`` across 1..9 read "±86 % in pressure", on small campaigns up to
"±2860 %".
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import optimize, stats

__all__ = [
    "POWER",
    "describe",
    "minimum_detectable",
    "noncentrality_for_power",
    "power_records",
    "testable",
]

#: Power at which the minimum detectable effect is stated.
POWER = 0.8


def noncentrality_for_power(df1: int, df2: int, alpha: float, power: float = POWER) -> float:
    """λ with P(F'(df1, df2, λ) > F_{1−α}(df1, df2)) = ``power`` (noncentral F)."""
    if df1 < 1 or df2 < 1 or not 0 < alpha < 1 or not 0 < power < 1:
        return float("nan")
    f_crit = stats.f.isf(alpha, df1, df2)

    def gap(lam: float) -> float:
        return float(stats.ncf.sf(f_crit, df1, df2, lam)) - power

    hi = 10.0
    while gap(hi) < 0:
        hi *= 4.0
        if hi > 1e8:
            return float("inf")
    return float(optimize.brentq(gap, 1e-9, hi, xtol=1e-8, rtol=1e-10))


def minimum_detectable(
    sigma: float, norm2: float, df1: int, df2: int, alpha: float, power: float = POWER
) -> float:
    """δ = σ·√(λ/‖r‖²): the effect the test detects with probability ``power`` at level α.

    ``norm2`` is ‖r‖², the squared length of the effect's pattern per unit δ (see the
    module docstring); ``sigma`` the residual standard deviation of the response.
    """
    if not (np.isfinite(sigma) and np.isfinite(norm2) and norm2 > 0 and sigma >= 0):
        return float("nan")
    lam = noncentrality_for_power(int(df1), int(df2), alpha, power)
    return float(sigma * np.sqrt(lam / norm2))


_RESPONSE_TEXT = {
    ("sinkage", "level"): ("pressure", True),
    ("sinkage", "shape"): ("the exponent n", False),
    ("shear", "level"): ("shear strength (c + σ tan φ)", True),
    ("shear", "K"): ("the shear modulus K", True),
}


def _size(relative: bool, delta: float) -> str:
    return f"±{100 * np.expm1(delta):.3g} %" if relative else f"±{delta:.3g}"


def testable(delta: float, observed: float | None) -> bool:
    """Whether an MDE ``delta`` lies within the ``observed`` range of the response (module
    docstring; an unknown range caps nothing)."""
    if observed is None or not np.isfinite(observed):
        return True
    return bool(np.isfinite(delta) and delta <= observed)


def describe(
    kind: str, response: str, delta: float, pattern: str, observed: float | None = None
) -> str:
    """The MDE as a sentence fragment with physical units, e.g. ``"±9.4 % in pressure for
    one level against the others"``; ``pattern`` says what δ shifts.  Beyond the
    ``observed`` range of the response: "not testable here" (module docstring)."""
    if not np.isfinite(delta):
        return "not computable (no residual degrees of freedom)"
    what, relative = _RESPONSE_TEXT[(kind, response)]
    if observed is not None and not testable(delta, observed):
        return (
            f"not testable here: the smallest detectable effect {pattern} exceeds the tests' "
            f"whole spread in {what} ({_size(relative, observed).lstrip('±')})"
        )
    return f"{_size(relative, delta)} in {what} {pattern}"


def power_records(table: pd.DataFrame, alpha: float) -> list[dict]:
    """One record per candidate of the diagnosis table that was tested and not found in any
    response: its minimum detectable effect per response, as a number and a sentence."""
    if table.empty or "mde" not in table:
        return []
    columns = ["kind", "soil", "candidate", "response", "significant", "p_value", "mde"]
    columns += ["role", "categorical", "span", "n_tests", "alpha_level"]
    columns += ["y_range"] if "y_range" in table else []
    # Plain records, grouped in order of first appearance (the table's per-test arrays stay
    # behind: iterating the frame itself costs more than all that follows).
    by_candidate: dict[tuple, list[dict]] = {}
    for record in table[columns].to_dict("records"):
        key = (record["kind"], record["soil"], record["candidate"])
        by_candidate.setdefault(key, []).append(record)
    out = []
    for (kind, soil, candidate), rows in by_candidate.items():
        if any(r["significant"] for r in rows) or all(np.isnan(r["p_value"]) for r in rows):
            continue
        first = rows[0]
        if first["role"] == "interaction":
            pattern = "for one cell against the additive model"
        elif first["role"] == "drift within blocks":
            pattern = "for one block's drift beside the common trend"
        elif first["categorical"]:
            pattern = "for one level against the others"
        else:
            pattern = f"across the observed range ({first['span']})"
        responses = {}
        for r in rows:
            if not np.isfinite(r["p_value"]):
                continue
            observed = r.get("y_range")
            ok = testable(r["mde"], observed)
            responses[r["response"]] = {
                "mde": float(r["mde"]) if np.isfinite(r["mde"]) and ok else None,
                "mde_uncapped": float(r["mde"]) if np.isfinite(r["mde"]) else None,
                "observed_range": None if observed is None else float(observed),
                "testable": ok,
                "p_value": float(r["p_value"]),
                "statement": describe(kind, r["response"], r["mde"], pattern, observed),
            }
        out.append(
            {
                "kind": kind,
                "soil": soil,
                "candidate": candidate,
                "role": first["role"],
                "n_tests": int(max(r["n_tests"] for r in rows)),
                "power": POWER,
                "alpha_level": float(first["alpha_level"]),
                "alpha": alpha,
                "responses": responses,
            }
        )
    return out
