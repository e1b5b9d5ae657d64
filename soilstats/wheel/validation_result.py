"""The frozen results of a wheel validation: :class:`WheelValidation`, :class:`WheelDiscovery`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from .. import evidence
from ..outputs import json_safe
from ..outputs.text import notes_block
from .geometry import Wheel
from .soil import PlateDraws
from .stress import PARAM_UNITS, StressAngles

if TYPE_CHECKING:
    from ..discovery.crossval import Gain
    from .slipsinkage import SlipExponent

__all__ = ["OLD_BAND_COLUMNS", "RUN_COLUMNS", "WheelDiscovery", "WheelValidation"]

#: The bounds of a run's band are ``lower`` and ``upper``, as in ``WheelPrediction.bands``;
#: in 0.1.0 they were named ``q05``/``q95``, which they are only at ``prob`` 0.9.  New
#: column → old: each frame of a validation carries a copy under the old name, and the JSON
#: and CSV write it, until 0.3.0 (docs/conventions.md, "Renamed").
OLD_BAND_COLUMNS = {
    f"{quantity}_{new}{unit}": f"{quantity}_{old}{unit}"
    for quantity, unit in (
        ("sinkage", "_m"),
        ("drawbar_pull", "_N"),
        ("torque", "_Nm"),
        ("sinkage_extended", "_m"),
        ("sinkage_heldout", "_m"),
        ("ext", ""),
    )
    for new, old in (("lower", "q05"), ("upper", "q95"))
}


def with_old_band_columns(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with a copy of each of its band columns under the old name (until 0.3.0)."""
    return frame.assign(
        **{old: frame[new] for new, old in OLD_BAND_COLUMNS.items() if new in frame}
    )


#: Columns of each run in ``to_dict()["runs"]`` (those present).
RUN_COLUMNS: tuple[str, ...] = (
    "run_id",
    "wheel",
    "slip",
    "slip_level",
    "beta_deg",
    "beta_level",
    "date",
    "W_N",
    "steady",
    "sinkage_measured_m",
    "sinkage_median_m",
    "sinkage_lower_m",
    "sinkage_upper_m",
    "sinkage_covered",
    "residual_m",
    "in_scope",
    "n_draws_used",
    "n_not_carried",
    "drawbar_pull_measured_N",
    "drawbar_pull_median_N",
    "drawbar_pull_lower_N",
    "drawbar_pull_upper_N",
    "drawbar_pull_covered",
    "torque_median_Nm",
    "torque_lower_Nm",
    "torque_upper_Nm",
    "sinkage_extended_median_m",
    "sinkage_extended_lower_m",
    "sinkage_extended_upper_m",
    "sinkage_heldout_median_m",
    "sinkage_heldout_lower_m",
    "sinkage_heldout_upper_m",
)
# ... and, until 0.3.0, the old names of its band columns (OLD_BAND_COLUMNS).
RUN_COLUMNS += tuple(OLD_BAND_COLUMNS[c] for c in RUN_COLUMNS if c in OLD_BAND_COLUMNS)
WIDTH = 96


def _mm(x: float | None) -> str:
    return "–" if x is None or not np.isfinite(x) else f"{1e3 * x:+.1f} mm"


def _pct(x: float | None) -> str:
    return "–" if x is None or not np.isfinite(x) else f"{100 * x:.0f} %"


@dataclass(frozen=True, eq=False)
class WheelDiscovery:
    """What the wheel model gets wrong, the slip-sinkage extension and its held-out gain.

    Attributes
    ----------
    tests : DataFrame
        The residual F-tests (:func:`soilstats.wheel.discovery.residual_tests`).
    findings : tuple of dict
        Significant candidates, strongest first: ``cause``, ``reading``, ``p_value`` (raw),
        ``p_adjusted`` (Holm), ``effect_size`` (partial η²), ``level_means``, ``extension``
        and ``gain`` (slip), or ``why_no_extension``.
    extension : str
        The extension's equation.
    coefficients : dict
        Wheel type → :class:`~soilstats.wheel.slipsinkage.SlipExponent` fitted on all its
        β = 0 runs.
    gains : dict
        ``"slip"``, ``"day"`` (both wheels) and ``"slip|<wheel>"`` … →
        :class:`~soilstats.discovery.crossval.Gain` on held-out runs.
    heldout : DataFrame
        Per held-out run and scheme: the fold, its coefficients, the extended band, errors.
    still_fails : list of dict
        Per wheel and slip (held out) and per β: base and extended error and coverage.
    runs : DataFrame
        Per run: the extended band (coefficients from all β = 0 runs of its wheel) and, for
        β = 0 runs, the band from the fold that held its slip condition out.
    """

    tests: pd.DataFrame
    findings: tuple[dict, ...]
    extension: str
    coefficients: dict[str, SlipExponent]
    gains: dict[str, Gain]
    heldout: pd.DataFrame = field(repr=False)
    still_fails: list
    runs: pd.DataFrame = field(repr=False)
    alpha: float = 0.05
    notes: tuple[str, ...] = ()

    def finding(self, cause: str) -> dict | None:
        """The finding of ``cause`` (``"slip"``, ``"beta"`` …), or None."""
        return next((f for f in self.findings if f["cause"] == cause), None)

    def to_dict(self) -> dict:
        tests = self.tests.drop(columns=[], errors="ignore")
        return json_safe(
            {
                "tests": tests.to_dict("records"),
                "alpha": self.alpha,
                "family": "Holm over every candidate tested",
                "findings": list(self.findings),
                "extension": {
                    "model": self.extension,
                    "source": "Ding, Gao, Deng, Tao, J. Cent. South Univ. Technol. 17(1) 129-135, "
                    "2010 (slip); CMU terramechanics/sigma.m (skid branch)",
                    "coefficients": {k: v.to_dict() for k, v in self.coefficients.items()},
                    "gains": {k: g.to_dict() for k, g in self.gains.items()},
                },
                "still_fails": list(self.still_fails),
                "notes": list(self.notes),
            }
        )

    def summary(self) -> str:
        lines = [" what the wheel model gets wrong ".center(WIDTH, "=")]
        t = self.tests
        lines.append(
            "Residual tests (measured − predicted sinkage; Holm over "
            f"{t['p_value'].notna().sum()}, alpha {self.alpha}):"
        )
        for _, r in t.iterrows():
            p = (
                "untested: " + r["reason"]
                if not np.isfinite(r["p_value"])
                else (
                    f"F({r['df1']}, {r['df2']}) = {r['statistic']:.3g}, p = {r['p_value']:.2g}, "
                    f"Holm {r['p_adjusted']:.2g}, partial η² {r['effect_size']:.2f}"
                )
            )
            mark = "*" if r["significant"] else " "
            lines.append(f" {mark} {r['candidate']:<13} within {r['within']:<26} {p}")
        lines.append("Findings (strongest first):")
        for f in self.findings:
            lines.append(f"  {f['cause']}: {f['reading']}")
        lines.append(f"Extension: {self.extension}")
        for name, c in self.coefficients.items():
            lines.append(
                f"  {name}: n1 = {c.n1:.3g} ({c.n_drive} runs), n2 = {c.n2:.3g} ({c.n_skid} runs)"
            )
        lines.append("Held-out gain (mean absolute sinkage error):")
        for key, g in self.gains.items():
            if key.startswith("day"):  # the same slip conditions stay in the fit
                key = f"{key} (repeatability)"
            lines.append(
                f"  {key:<14} {1e3 * g.base:.2f} -> {1e3 * g.extended:.2f} mm ({g.relative:+.0%}; "
                f"difference {1e3 * g.difference:.2f} ± {1e3 * g.stderr:.2f} mm, {g.folds} folds): "
                + evidence.verdict(g.difference, g.stderr, g.relative)
            )
        lines.append("Where the extended model still fails:")
        for r in self.still_fails:
            lines.append(
                f"  {r['wheel']:<8} {r['level']:<10} "
                f"measured {1e3 * r['measured_mean_m']:5.1f} mm, "
                f"error {1e3 * r['base_mae_m']:5.1f} -> {1e3 * r['extended_mae_m']:5.1f} mm, "
                f"band covers {_pct(r['extended_coverage_90'])} ({r['where']})"
            )
        lines.extend(notes_block(self.notes))
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()


@dataclass(frozen=True, eq=False)
class WheelValidation:
    """Measured wheel runs against their prediction from plate-identified soil parameters.

    Attributes
    ----------
    runs : DataFrame
        One row per run (:data:`RUN_COLUMNS`): measured and predicted sinkage (the median
        and the band's ``lower`` and ``upper`` bounds, the (1 − prob)/2 and (1 + prob)/2
        quantiles), whether the band covers it, residual (measured − median), scope.
    groups : DataFrame
        Coverage, bias (predicted − measured), MAE per wheel, wheel × slip, wheel × β and
        wheel × day (``quantity``, ``by``, ``scope``, ``wheel``, ``level`` …).
    coverage, bias : dict
        The headline: β = 0 runs, all runs, near-zero slip, per wheel; bias trends.
    plate : PlateDraws
        The soil's draws and where they came from (population or pooled, and why).
    sources : dict
        Parameter → where it came from (plates, or a user prior: never invented).
    moduli : dict
        Wheel → the plate modulus (kc/b + kφ …) of the draws at its width b.
    unpredictable : dict
        Quantity → why it is not predicted (drawbar pull and torque without shear priors).
    tests : DataFrame
        Residual F-tests; ``discovery`` (:class:`WheelDiscovery`) the extension and its gain.
    sensitivity : list of dict
        Near-zero-slip predictions under other choices (Bekker's b, rear contact).
    excluded : list of dict
        Runs left out of the headline or of all comparisons, with the reason.
    """

    runs: pd.DataFrame = field(repr=False)
    groups: pd.DataFrame = field(repr=False)
    coverage: dict
    bias: dict
    plate: PlateDraws = field(repr=False)
    sources: dict
    moduli: dict
    wheels: dict[str, Wheel]
    law: str
    angles: StressAngles
    prob: float
    seed: int
    unpredictable: dict
    tests: pd.DataFrame = field(repr=False)
    discovery: WheelDiscovery | None
    sensitivity: list
    excluded: list
    notes: tuple[str, ...] = ()
    caveats: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        """The JSON-ready content (issue #34's schema: ``runs``, ``coverage_90``, ``bias``,
        ``params``, ``notes``, and the rest); no NaN."""
        runs = self.runs[[c for c in RUN_COLUMNS if c in self.runs]]
        draws = self.plate.draws
        quantiles = {
            k: {
                "median": float(np.median(draws[k])),
                "q05": float(np.quantile(draws[k], 0.05)),
                "q95": float(np.quantile(draws[k], 0.95)),
                "unit": PARAM_UNITS.get(k, ""),
            }
            for k in draws.columns
            if k in PARAM_UNITS
        }
        moduli = {
            k: {kk: vv for kk, vv in v.items() if kk != "use"} for k, v in self.moduli.items()
        }
        return json_safe(
            {
                "runs": runs.to_dict("records"),
                "coverage_90": self.coverage,
                "bias": self.bias,
                "params": {
                    "sources": dict(self.sources),
                    "units": {k: PARAM_UNITS.get(k, "") for k in self.sources},
                    "draws": self.plate.to_dict(),
                    "draw_quantiles": quantiles,
                    "modulus_at_wheel_width": moduli,
                },
                "predicted": ["sinkage_m"]
                + ([] if self.unpredictable else ["drawbar_pull_N", "torque_Nm"]),
                "unpredictable": dict(self.unpredictable),
                "groups": self.groups.to_dict("records"),
                "discovery": None if self.discovery is None else self.discovery.to_dict(),
                "sensitivity": list(self.sensitivity),
                "excluded": list(self.excluded),
                "model": {
                    "name": "Wong-Reece rigid wheel (longitudinal)",
                    "law": self.law,
                    "angles": self.angles.to_dict(),
                    "wheels": {k: w.to_dict() for k, w in self.wheels.items()},
                    "prob": self.prob,
                    "seed": self.seed,
                },
                "notes": list(self.notes),
                "caveats": list(self.caveats),
            }
        )

    def summary(self) -> str:
        """Readable report: the soil, coverage and bias per wheel, slip and β, the findings."""
        c, b = self.coverage, self.bias
        lines = [" wheel runs against plate-identified soil ".center(WIDTH, "=")]
        lines.append(
            f"Soil: {self.plate.law} from {self.plate.n_tests} plate tests — {self.plate.reason}"
        )
        for k, v in self.sources.items():
            lines.append(f"  {k:>5} [{PARAM_UNITS.get(k, '')}]: {v}")
        for name, m in self.moduli.items():
            lines.append(
                f"  modulus at b = {1e3 * m['b_m']:g} mm ({name}): min {m['min']:.3g}, median "
                f"{m['median']:.3g} N/m^(n+2); {m['nonpositive']} of {m['draws']} draws ≤ 0"
            )
        lines.append("-" * WIDTH)
        lines.append("Sinkage, 90 % band coverage and bias (predicted − measured):")
        for wheel, cov in c["by_wheel"].items():
            bw = b["by_wheel"][wheel]
            for scope in ("beta_0", "near_zero_slip_beta_0", "all_runs"):
                lines.append(
                    f"  {wheel:<8} {scope:<22} "
                    f"covered {cov[scope]['covered']:>3}/{cov[scope]['runs']:<3}"
                    f" ({_pct(cov[scope]['coverage_90'])}), bias {_mm(bw[scope]['mean_m'])}, "
                    f"MAE {_mm(bw[scope]['mae_m'])[1:]}"
                )
        lines.append("Per wheel and slip condition (β = 0) and per β (all slips):")
        g = self.groups
        for by in ("wheel × slip", "wheel × β"):
            rows = g[(g["by"] == by) & (g["quantity"] == "sinkage")]
            for _, r in rows.iterrows():
                label = f"s = {r['level']:g}" if by == "wheel × slip" else f"β = {r['level']}°"
                lines.append(
                    f"  {r['wheel']:<8} {label:<10} measured {1e3 * r['measured_mean']:5.1f} mm, "
                    f"predicted {1e3 * r['predicted_mean']:5.1f} mm, "
                    f"covered {r['covered']}/{r['runs']}"
                )
        if "drawbar_pull_beta_0" in c:
            lines.append("Drawbar pull (β = 0, with the stated shear priors):")
            for wheel, cov in c["drawbar_pull_beta_0"].items():
                bb = b["drawbar_pull_beta_0"][wheel]
                lines.append(
                    f"  {wheel:<8} covered {cov['covered']}/{cov['runs']} "
                    f"({_pct(cov['coverage_90'])}),"
                    f" bias {bb['mean_N']:+.2f} N"
                )
        for q, reason in self.unpredictable.items():
            lines.append(f"NOT PREDICTED: {q} — {reason}")
        lines.append("Bias trends:")
        for t in b["trend"]:
            lines.append(
                f"  {t['wheel']:<8} vs {t['against']:<30} "
                f"{t['slope']:+.3g} ± {t['stderr']:.2g} {t['unit']}"
            )
        if self.discovery is not None:
            lines.append(self.discovery.summary())
        if self.sensitivity:
            lines.append("Sensitivity (near-zero slip, β = 0):")
            for s in self.sensitivity:
                lines.append(
                    f"  {s['wheel']:<8} {s['case']:<52} "
                    f"predicted {1e3 * s['predicted_mean_m']:5.1f} mm "
                    f"(measured {1e3 * s['measured_mean_m']:.1f})"
                )
        for e in self.excluded:
            lines.append(f"Excluded from the headline ({len(e['runs'])} runs): {e['reason']}")
        lines.extend(notes_block([*self.notes, *self.caveats]))
        lines.append("=" * WIDTH)
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()
