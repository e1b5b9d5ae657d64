"""Do the Mohr–Coulomb lines τ = c + σ·tanφ (Eq. 15) differ between the factor's levels?

Data: one point per shear test — its mean normal pressure σ and its steady-state shear
stress τ_ss (the points of the paper's Figs. 11–14; a test, not a sample, is the unit of
replication, since the samples of one test share its preparation).  Tests that never reach a
steady state are left out and listed.

Tests, per soil (from :func:`soilstats.statistics.ancova` with ``variance="fitted"``: lines by
weighted least squares, the scatter of τ_ss allowed to grow with σ as each preparation draws
its own φ; ordinary least squares rejected a true null of the slopes at ~0.11 for α = 0.05):

* ``phi`` — do the friction angles differ?  slopes, parallel vs separate lines;
* ``c`` — do the cohesions differ?  H0: equal intercepts *in the separate-lines model*
  (a Wald F-test; the ANCOVA's intercept test assumes a common slope, and when the slopes
  differ it compares the lines at the mean σ, which is not c);
* ``line`` — do the lines differ at all (c or φ)?  common line vs separate lines.

c is an extrapolation to σ = 0 from tests at 3–20 kPa, so its interval is wide: a few tens of
Pa of cohesion are often not resolved, as the paper notes for its Table 6.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
from scipy import stats

from ..identification.conditions import condition_label
from ..statistics import StatisticsInputError, TestResult, ancova, effect_row

if TYPE_CHECKING:
    from ..statistics.analysis_of_covariance import AncovaResult
    from .spec import StudySpec

__all__ = ["shear_effects"]


def _line_test(result: AncovaResult) -> TestResult:
    cmp = result.comparison
    ssr0, df0 = cmp.loc["common", "ssr"], cmp.loc["common", "df_resid"]
    ssr2, df2 = cmp.loc["separate", "ssr"], cmp.loc["separate", "df_resid"]
    ssr0, df0, ssr2, df2 = (float(v) for v in (ssr0, df0, ssr2, df2))  # type: ignore[arg-type]  # pandas-stubs: .loc[row, col] is any scalar
    dfn = df0 - df2
    f = ((ssr0 - ssr2) / dfn) / (ssr2 / df2)
    return TestResult(
        test="ANCOVA F-test of H0: one line (common c and φ)",
        statistic=float(f),
        p_value=float(stats.f.sf(f, dfn, df2)),
        df_num=float(dfn),
        df_den=float(df2),
        effect_size=float((ssr0 - ssr2) / ssr0),
        effect_size_name="partial_eta_sq",
    )


def shear_effects(per_test: pd.DataFrame, spec: StudySpec, soil: str) -> dict:
    """ANCOVA tests of c, φ and the whole line for one soil (see the module docstring).

    Returns
    -------
    dict
        ``effects`` (rows for the verdicts), ``anova`` (the model comparison, tidy),
        ``lines`` (per-level c [Pa], φ [deg] with standard errors), ``notes``.
    """
    factor = spec.factor
    frame = per_test.assign(level=per_test[factor].map(condition_label))
    notes = []
    unsteady = frame[~frame["steady"].astype(bool) | frame["tau_ss_Pa"].isna()]
    if len(unsteady):
        notes.append(
            f"{soil}: {len(unsteady)} test(s) never reached a steady state and are left out "
            f"({', '.join(unsteady['test_id'].astype(str))})"
        )
    data = frame.drop(unsteady.index)
    try:
        result = ancova(data, "tau_ss_Pa", "sigma_mean_Pa", "level", variance="fitted")
    except StatisticsInputError as err:
        notes.append(f"{soil}: not tested — {err}")
        return {"effects": [], "anova": pd.DataFrame(), "lines": pd.DataFrame(), "notes": notes}
    tests = {
        "phi": result.slope_test,
        "c": result.separate_intercepts_test,
        "line": _line_test(result),
    }
    effects = []
    for resp in spec.responses:
        row = effect_row(soil, resp.name, factor, tests[resp.name])
        row.update(blocks="", n_tests=len(data), margin=np.nan, largest_difference=np.nan)
        lines = result.lines
        if resp.name in ("c", "phi"):
            col = "intercept" if resp.name == "c" else "phi_deg"
            row["largest_difference"] = float(lines[col].max() - lines[col].min())
            if resp.margin is not None:
                row["margin"] = resp.margin
        effects.append(row)
    comparison = result.comparison.reset_index(names="model")
    comparison.insert(0, "soil", soil)
    lines = result.lines.reset_index(names="level")
    lines.insert(0, "soil", soil)
    lines["phi_stderr_deg"] = np.degrees(lines["slope_stderr"] / (1.0 + lines["slope"] ** 2))
    return {"effects": effects, "anova": comparison, "lines": lines, "notes": notes}
