"""What the wheel model gets wrong: residual structure of wheel runs, tested like ``discover``.

The residual of a run is measured − predicted (median) sinkage.  Each candidate cause is an
F-test of the residuals within strata of the other design factors (the machinery of
:mod:`soilstats.discovery.ftests`), and all p-values form one Holm family
(:func:`soilstats.statistics.verdicts`):

===========  ======================================  ========================================
candidate    tested as                               within strata of
===========  ======================================  ========================================
slip         levels (the runs' slip conditions)      wheel × β
beta         levels (β conditions)                   wheel × slip
wheel        levels                                  slip × β
day          levels (dates)                          wheel × slip × β (the repeats of a cell)
load         linear trend in W                       wheel × slip × β
slip × beta  interaction after both main effects     wheel
slip × wheel interaction                             β
beta × wheel interaction                             slip
===========  ======================================  ========================================

A significant candidate is a *finding*; findings are ranked by partial η², and the known
candidates carry their physical reading (``READINGS``).  Which one the model can be extended
for, and the held-out gain, are decided in :mod:`soilstats.wheel.validation`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

__all__ = ["CANDIDATES", "READINGS", "residual_tests"]

#: name → (column, categorical, strata columns)
CANDIDATES: dict[str, tuple[str, bool, tuple[str, ...]]] = {
    "slip": ("slip_level", True, ("wheel", "beta_level")),
    "beta": ("beta_level", True, ("wheel", "slip_level")),
    "wheel": ("wheel", True, ("slip_level", "beta_level")),
    "day": ("date", True, ("wheel", "slip_level", "beta_level")),
    "load": ("W_N", False, ("wheel", "slip_level", "beta_level")),
}
INTERACTIONS: dict[str, tuple[str, str, tuple[str, ...]]] = {
    "slip × beta": ("slip_level", "beta_level", ("wheel",)),
    "slip × wheel": ("slip_level", "wheel", ("beta_level",)),
    "beta × wheel": ("beta_level", "wheel", ("slip_level",)),
}
#: What a finding means physically, for the candidates the wheel model knows.
READINGS: dict[str, str] = {
    "slip": (
        "sinkage grows with slip and skid (slip sinkage): the static pressure–sinkage law "
        "fixes the sinkage by the load, and slip moves it only through the stress angles"
    ),
    "beta": (
        "sinkage grows with the slip angle: lateral shear, side-wall and bulldozing forces "
        "(Ishigami et al. 2007) are outside the longitudinal model"
    ),
    "wheel": "the two wheels differ beyond what their geometry (r, r_s, b) gives the model",
    "day": (
        "the days differ beyond the repeats of a condition: preparation, sand state or the "
        "sinkage datum changing from day to day"
    ),
    "load": "the residual follows the measured load within a condition: the load law is off",
    "slip × beta": "the slip effect depends on the slip angle",
    "slip × wheel": "the slip effect differs between the wheels (grousers dig at high slip)",
    "beta × wheel": "the slip-angle effect differs between the wheels",
}


def _codes(frame: pd.DataFrame, column: str) -> np.ndarray:
    """Level codes 0…k−1 of a column (dates as text)."""
    return pd.factorize(frame[column].astype(str) if column == "date" else frame[column])[0]


def residual_tests(
    runs: pd.DataFrame, residual: str = "residual_m", *, alpha: float = 0.05
) -> pd.DataFrame:
    """One row per candidate: F-test of the residuals (module table), Holm-adjusted.

    Columns: ``candidate``, ``kind`` (``main``/``interaction``), ``within`` (the strata),
    ``statistic``, ``df1``, ``df2``, ``p_value`` (raw), ``p_adjusted`` (Holm over all rows
    tested), ``significant``, ``effect_size`` (partial η²), ``reason`` (why a candidate
    could not be tested; those rows have no p-value and are not in the family).
    """
    # loaded when a test is made: the discovery package and statsmodels are heavy imports
    from ..discovery.ftests import (  # deferred: scipy.stats
        interaction_test,
        strata_codes,
        strata_test,
    )
    from ..statistics import verdicts  # deferred: statsmodels

    y = runs[residual].to_numpy(float)
    rows = []
    for name, (column, categorical, within) in CANDIDATES.items():
        # runs without a value of the candidate (undated runs) are left out of its test only
        given = runs[column].notna() if column in runs else pd.Series(False, index=runs.index)
        if not given.any():
            rows.append(_row(name, "main", within, {"reason": f"no {column} column"}))
            continue
        sub = runs[given]
        present = [c for c in within if c in sub and sub[c].notna().all()]
        strata = strata_codes([_codes(sub, c) for c in present], len(sub))
        x = _codes(sub, column) if categorical else sub[column].to_numpy(float)
        res = strata_test(
            y[given.to_numpy()], x, categorical=categorical, strata=strata, log_scale=False
        )
        if not given.all():
            res = {**res, "reason": f"{int((~given).sum())} runs without {column} left out"}
        rows.append(_row(name, "main", within, res))
    for name, (a, b, within) in INTERACTIONS.items():
        strata = strata_codes([_codes(runs, c) for c in within], len(runs))
        res = interaction_test(y, _codes(runs, a), _codes(runs, b), strata=strata)
        rows.append(_row(name, "interaction", within, res))
    table = pd.DataFrame(rows)
    tested = table["p_value"].notna()
    table["p_adjusted"] = np.nan
    table["significant"] = False
    if tested.any():
        effects = table.loc[tested].assign(
            soil="wheel runs", response="sinkage residual", factor=table["candidate"], test="F"
        )
        judged = verdicts(effects, alpha=alpha)
        table.loc[tested, "p_adjusted"] = judged["p_adjusted"].to_numpy()
        table.loc[tested, "significant"] = judged["significant"].to_numpy()
    table["significant"] = table["significant"].astype(bool)
    table.attrs["alpha"] = alpha
    return table


def _row(name: str, kind: str, within: Sequence[str], res: dict) -> dict:
    return {
        "candidate": name,
        "kind": kind,
        "within": " × ".join(w.replace("_level", "") for w in within) or "–",
        "statistic": float(res.get("statistic", np.nan)),
        "df1": int(res.get("df1", 0) or 0),
        "df2": int(res.get("df2", 0) or 0),
        "p_value": float(res.get("p_value", np.nan)),
        "effect_size": float(res.get("effect_size", np.nan)),
        "reason": str(res.get("reason", "") or ""),
    }
