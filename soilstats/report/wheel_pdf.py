"""The PDF report of ``soilstats wheel``: how well plate-identified soil predicts a wheel.

Page 1: the question, the data, and the answer in sentences with numbers — coverage and bias
per wheel type, what grows that the model cannot follow, the extension's held-out gain — with
the predicted-against-measured figure.  Then the validation tables (per wheel, slip condition
and slip angle), what the model gets wrong (the residual tests and figures), the extension
and its gain, the sensitivity to Bekker's b and the exit angle, drawbar pull (or why it is not
predicted), and the caveats of the data.  Everything in ``wheel.json`` but the per-run rows
(in ``wheel_runs.csv``) is in the PDF.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from .. import evidence
from ..outputs.files import output_path
from .document import Document, strong
from .front import data_origin, front_page
from .wheel_calibration_pdf import calibration_conclusion, calibration_sections
from .wheel_figures import (
    beta_figure,
    day_figure,
    drawbar_figure,
    extension_figure,
    predicted_figure,
)

if TYPE_CHECKING:
    from ..discovery.crossval import Gain
    from ..outputs.provenance import Provenance
    from ..wheel.calibration.validate import CalibrationReport
    from ..wheel.validation_result import WheelDiscovery, WheelValidation

__all__ = ["write_report"]


def _mm(x: float) -> str:
    return f"{1e3 * x:.1f} mm"


def _signed_mm(x: float) -> str:
    return f"{1e3 * x:+.1f} mm"


def _answer(res: WheelValidation) -> list:
    """The title's answer first: "no" while the band holds fewer than half the runs; what
    the band holds; and the bias by slip (never a lone mean over a U-shaped error), with the
    MAE beside it for drawbar pull, whose errors of either sign a mean would cancel."""
    cov = res.coverage["beta_0"]
    verdict = (
        "No" if cov["coverage_90"] < 0.5 else ("Partly" if cov["coverage_90"] < 0.8 else "Yes")
    )
    g = res.groups
    text = (
        f"the 90 % band from plates alone holds {cov['covered']} of {cov['runs']} β = 0 runs "
        f"({cov['coverage_90']:.0%}). It is PARAMETER UNCERTAINTY ONLY (plate posterior and "
        "test-to-test scatter; no model discrepancy, stress angles and datum fixed)"
    )
    sink = _by_slip(g, "sinkage")
    if sink is not None:
        worst = sink["bias"].abs().idxmax()
        text += (
            "; its sinkage bias (predicted − measured) by slip: "
            + ", ".join(f"s = {lv:g}: {_signed_mm(r.bias)}" for lv, r in sink.iterrows())
            + f" (largest at s = {worst:g})"
        )
    out = [[strong(f"{verdict}: "), text + "."]]
    pull = _by_slip(g, "drawbar_pull")
    if pull is not None:
        out.append(
            [
                strong("Drawbar pull by slip (from the stated shear priors): "),
                "MAE / bias "
                + ", ".join(
                    f"s = {lv:g}: {r.mae:.1f} / {r.bias:+.1f} N" for lv, r in pull.iterrows()
                )
                + ".",
            ]
        )
    return out


def _by_slip(groups: pd.DataFrame, quantity: str) -> pd.DataFrame | None:
    """Mean bias and MAE over the wheel types at each slip condition (β = 0), or None."""
    if groups.empty:
        return None
    rows = groups[(groups["by"] == "wheel × slip") & (groups["quantity"] == quantity)]
    if rows.empty:
        return None
    return rows.groupby("level")[["bias", "mae"]].mean()


def _conclusion(res: WheelValidation) -> list:
    c, b = res.coverage, res.bias
    out: list = _answer(res)
    per_wheel = []
    for wheel, cov in c["by_wheel"].items():
        near, bw = cov["near_zero_slip_beta_0"], b["by_wheel"][wheel]
        # the MAE beside the mean bias: over a U-shaped error in slip a mean alone hides
        per_wheel.append(
            f"{wheel} {cov['beta_0']['covered']}/{cov['beta_0']['runs']}, MAE "
            f"{_mm(bw['beta_0']['mae_m'])}, mean bias {_signed_mm(bw['beta_0']['mean_m'])} "
            f"(at s ≈ 0: {near['covered']}/{near['runs']}, "
            f"{_mm(bw['near_zero_slip_beta_0']['predicted_mean_m'])} predicted, "
            f"{_mm(bw['near_zero_slip_beta_0']['measured_mean_m'])} measured)"
        )
    out.append(
        [
            strong("Sinkage from plates alone: "),
            f"the {_LAW.get(res.plate.law, res.plate.law)} law from {res.plate.n_tests} plate "
            f"tests ({res.plate.kind} draws) puts {c['beta_0']['covered']} of "
            f"{c['beta_0']['runs']} β = 0 runs inside its 90 % band "
            f"({c['beta_0']['coverage_90']:.0%}): " + "; ".join(per_wheel) + ".",
        ]
    )
    sens = _sensitivity_sentence(res)
    if sens:
        out[-1].append(" " + sens)
    g = res.groups
    slip = g[(g["by"] == "wheel × slip") & (g["quantity"] == "sinkage")]
    if len(slip):
        lo, hi = slip.loc[slip["level"].idxmin()], slip.loc[slip["level"].idxmax()]  # type: ignore[call-overload]  # pandas-stubs: idxmin is a Hashable label
        out.append(
            [
                strong("What the model gets wrong: "),
                "sinkage grows with slip and skid, and the model's hardly does: at β = 0 the "
                f"{lo['wheel']} wheel sinks {_mm(lo['measured_mean'])} at s = {lo['level']:g} "
                f"(predicted {_mm(lo['predicted_mean'])}), at s = {hi['level']:g} "
                f"{_mm(hi['measured_mean'])} (predicted {_mm(hi['predicted_mean'])}). "
                + _beta_sentence(res),
            ]
        )
    slip_sinkage = _slip_sinkage(res.discovery)
    if slip_sinkage:
        out.append(slip_sinkage)
    if res.unpredictable:
        out.append(
            [
                strong("Not predicted: "),
                "drawbar pull and torque: no shear test measured c, φ, K and no prior was "
                "stated (--prior phi=normal:29:4 … predicts them).",
            ]
        )
    elif "drawbar_pull_beta_0" in c:
        dp = "; ".join(
            f"{w}: {v['covered']} of {v['runs']}" for w, v in c["drawbar_pull_beta_0"].items()
        )
        out.append(
            [
                strong("Drawbar pull "),
                f"with the stated (not measured) shear priors: the band holds {dp} β = 0 runs.",
            ]
        )
    return out


def _slip_sinkage(disc: WheelDiscovery | None) -> list:
    """Page 1's sentence on the named cause, its extension and the held-out gains."""
    if disc is None or not disc.gains:
        return []
    slip_gain, day_gain = disc.gains.get("slip"), disc.gains.get("day")
    coefs = "; ".join(
        f"{w}: n1 = {f.n1:.2f}, n2 = {f.n2:.2f}" for w, f in disc.coefficients.items()
    )
    text = (
        f"the residual tests name slip (Holm p = {_p(disc, 'slip')}) as the cause. The "
        "exponent N = n + n1·s, n + n2·|s| in skid (Ding et al. 2010), fitted on the runs "
        f"({coefs}), "
    )
    if slip_gain is not None:
        text += (
            f"cuts the held-out mean absolute error from {_mm(slip_gain.base)} to "
            f"{_mm(slip_gain.extended)} ({slip_gain.relative:+.0%}, {_real(slip_gain)}) "
            "leaving whole slip conditions out"
        )
    if day_gain is not None:
        text += (
            f"; leaving whole days out — repeatability: the same slip conditions stay in the "
            f"fit through other days' repeats, so this does not test new slips — "
            f"{_mm(day_gain.extended)} ({day_gain.relative:+.0%}, {_real(day_gain)})"
        )
    return [strong("Slip sinkage: "), text + ". " + _fails_sentence(disc)]


_LAW = {"bekker": "Bekker", "bernstein": "Bernstein", "reece": "Reece"}


def _sensitivity_sentence(res: WheelValidation) -> str:
    sens = pd.DataFrame(res.sensitivity)
    if sens.empty:
        return ""
    rear = sens[sens["case"].str.startswith("rear")]
    half = sens[sens["case"].str.startswith("Bekker")]
    parts = []
    if len(rear):
        parts.append(
            "an exit behind the bottom (θ2 = −0.5 θ1, not measured) would predict "
            + ", ".join(_mm(v) for v in rear["predicted_mean_m"])
        )
    if len(half):
        parts.append(
            "Bekker's b = half the width " + ", ".join(_mm(v) for v in half["predicted_mean_m"])
        )
    return "At s ≈ 0, " + "; ".join(parts) + "."


def _p(disc: WheelDiscovery, cause: str) -> str:
    row = disc.tests[disc.tests["candidate"] == cause]
    return "–" if row.empty else f"{float(row['p_adjusted'].iloc[0]):.1g}"


def _real(gain: Gain) -> str:
    """The gain in the one vocabulary of evidence (soilstats.evidence): word, d ± SE, z."""
    return evidence.describe(gain.difference, gain.stderr, gain.relative, unit="mm", scale=1e3)


def _beta_sentence(res: WheelValidation) -> str:
    g = res.groups
    beta = g[(g["by"] == "wheel × β") & (g["quantity"] == "sinkage")]
    if beta["level"].nunique() < 2:
        return ""
    top = beta[beta["level"] == beta["level"].max()]
    return (
        f"With slip angle it grows further: at β = {top['level'].iloc[0]}° the runs sink "
        + ", ".join(f"{_mm(r['measured_mean'])} ({r['wheel']})" for _, r in top.iterrows())
        + " on average, where the longitudinal model predicts "
        + ", ".join(f"{_mm(r['predicted_mean'])}" for _, r in top.iterrows())
        + "; this is a finding of the data, outside the model's domain."
    )


def _fails_sentence(disc: WheelDiscovery) -> str:
    fails = pd.DataFrame(disc.still_fails)
    if fails.empty:
        return ""
    slip = fails[fails["where"].str.startswith("β = 0")]
    worst = slip.sort_values("extended_mae_m", ascending=False).head(2)
    parts = [
        f"{r['wheel']} at {r['level']} ({_mm(r['extended_mae_m'])})" for _, r in worst.iterrows()
    ]
    return (
        "It still fails where its straight line in s cannot bend: held out, the largest errors "
        "are " + " and ".join(parts) + "; and at high slip angle (β ≠ 0 runs, never fitted)."
    )


def _tests_table(doc: Document, disc: WheelDiscovery | _Tests) -> None:
    t = disc.tests.copy()
    t["result"] = [
        r["reason"]
        if not np.isfinite(r["p_value"])
        else f"F({r['df1']}, {r['df2']}) = {r['statistic']:.3g}"
        for _, r in t.iterrows()
    ]
    doc.table(
        t[["candidate", "within", "result", "p_value", "p_adjusted", "effect_size", "significant"]],
        caption="Residual tests (measured − predicted sinkage, all runs): each candidate within "
        "strata of the other design factors; p raw and Holm-adjusted over all rows tested; "
        "effect size partial η².",
        labels={"p_value": "p", "p_adjusted": "p (Holm)", "effect_size": "partial η²"},
        formats={"p_value": ".2g", "p_adjusted": ".2g", "effect_size": ".2f"},
        align_numbers=False,
    )


def _group_table(
    doc: Document, res: WheelValidation, by: str, caption: str, level_label: str
) -> None:
    g = res.groups
    rows = g[(g["by"] == by) & (g["quantity"] == "sinkage")].copy()
    if rows.empty:
        return
    if by == "wheel × slip":
        rows = rows[rows["scope"] == "β = 0"]
    table = pd.DataFrame(
        {
            "wheel": rows["wheel"],
            level_label: rows["level"],
            "runs": rows["runs"],
            "measured (mm)": rows["measured_mean"] * 1e3,
            "predicted (mm)": rows["predicted_mean"] * 1e3,
            "bias (mm)": rows["bias"] * 1e3,
            "in band": rows["covered"].astype(str) + " / " + rows["runs"].astype(str),
        }
    )
    doc.table(
        table,
        caption=caption,
        formats={"measured (mm)": ".1f", "predicted (mm)": ".1f", "bias (mm)": "+.1f"},
    )


def write_report(
    result: WheelValidation,
    path: str | Path,
    *,
    provenance: Provenance | None = None,
    overwrite: bool = False,
    calibration: CalibrationReport | None = None,
    defaults: dict[str, str] | None = None,
    default_warnings: dict[str, str] | None = None,
) -> int:
    """Write the typeset wheel-validation report of ``result`` to ``path``; return its pages.

    ``defaults``: the settings and geometry the user did not give, on page 1; of them,
    ``default_warnings`` those that move a verdict (:func:`soilstats.wheel.defaults.
    moved_verdicts`), each a warning there.

    With ``calibration`` (``--calibrate``) page 1 also gives the held-out answers of the
    calibrated wheel and the body its sections (:mod:`.wheel_calibration_pdf`)."""
    path = output_path(Path(path).parent, Path(path).name, overwrite=overwrite)
    res = result
    doc = Document(
        "Do plate-identified soil parameters predict this wheel?",
        subtitle="soilstats wheel — Wong–Reece rigid wheel, soil from plate tests only",
        provenance=provenance,
    )
    source = provenance.campaign if provenance is not None else ""
    runs = res.runs
    wheels = ", ".join(f"{w.describe()}" for w in res.wheels.values())
    front_page(
        doc,
        question=[
            "The soil's pressure–sinkage law is identified on plate tests alone. Predicting "
            "every measured wheel run at its own measured load, does the 90 % band hold the "
            "measured sinkage, how biased is it, per wheel type, slip and slip angle — and what "
            "does the wheel model get wrong?"
        ],
        data=[
            data_origin(source) if source else "data passed in memory",
            f": {res.plate.n_tests} plate tests; {len(runs)} wheel runs ({wheels}), slip "
            f"{runs['slip'].min():.2g} to {runs['slip'].max():.2g}, slip angle "
            f"{runs['beta_level'].min()}–{runs['beta_level'].max()}°, load "
            f"{runs['W_N'].min():.0f}–{runs['W_N'].max():.0f} N. The wheel runs never enter the "
            "soil parameters that predict them.",
        ],
        conclusion=_conclusion(res)
        + (calibration_conclusion(calibration) if calibration is not None else []),
        defaults=defaults,
        default_warnings=default_warnings,
    )
    fig, caption = predicted_figure(res)
    doc.figure(fig, caption, width="94%")
    doc.page_break()

    _method(doc, res)
    _validation(doc, res)
    _what_is_wrong(doc, res)
    if res.discovery is not None and res.discovery.gains:
        _extension(doc, res, res.discovery)
    if res.sensitivity:
        _sensitivity(doc, res)
    _forces_and_caveats(doc, res, calibration)
    doc.provenance_section()
    return doc.render(path)


def _method(doc: Document, res: WheelValidation) -> None:
    """Soil, model, plate moduli at the wheel's width, and what coverage and bias mean."""
    doc.heading("Method")
    doc.bullets(
        [
            f"Soil: {res.plate.reason}. Parameter sources: "
            + "; ".join(f"{k}: {v}" for k, v in res.sources.items())
            + ".",
            "Model: the Wong–Reece rigid wheel (docs/wheel.md), θm/θ1 = "
            f"{res.angles.a0:g} + {res.angles.a1:g}·s, θ2/θ1 = {res.angles.b0:g} + "
            f"{res.angles.b1:g}·s (stated inputs), each run at its own measured load W; "
            "longitudinal only, so β ≠ 0 runs are predicted as if β = 0.",
            *[n for n in res.notes if n.startswith("Bekker's b")],
            *[
                f"Plate modulus at the wheel width b = {_mm(m['b_m'])} ({w}): median "
                f"{m['median']:.3g}, smallest {m['min']:.3g} N/m^(n+2); {m['nonpositive']} of "
                f"{m['draws']} draws ≤ 0"
                for w, m in res.moduli.items()
            ],
            "Coverage: share of runs whose measured sinkage lies in the 5 %–95 % band of the "
            "draws; bias: predicted median − measured (> 0: the model sinks too deep). The "
            "headline is over β = 0 runs, the model's domain.",
        ]
    )


def _validation(doc: Document, res: WheelValidation) -> None:
    """Sinkage per wheel and slip, per wheel and slip angle; the bias trends."""
    doc.heading("Validation")
    _group_table(
        doc, res, "wheel × slip",
        "Sinkage per wheel and slip condition, β = 0 runs: means over the runs, and how many "
        "runs the predicted 90 % band holds.",
        "slip s",
    )  # fmt: skip
    _group_table(
        doc, res, "wheel × β",
        "Sinkage per wheel and slip angle, all slips (β ≠ 0 predicted as if β = 0).",
        "β (°)",
    )  # fmt: skip
    trends = pd.DataFrame(res.bias["trend"])
    if len(trends):
        doc.table(
            trends[["wheel", "against", "slope", "stderr", "unit", "runs"]],
            caption="Trend of the bias (predicted − measured) with slip and slip angle: "
            "least-squares slope ± its standard error.",
            formats={"slope": ".3g", "stderr": ".2g"},
        )


def _what_is_wrong(doc: Document, res: WheelValidation) -> None:
    """The residual tests, their findings, and the slip-angle and day figures."""
    runs = res.runs
    disc = res.discovery
    doc.heading("What the wheel model gets wrong")
    _tests_table(doc, disc if disc is not None else _Tests(res.tests))
    findings = disc.findings if disc is not None else ()
    if findings:
        doc.numbered(
            [strong(f"{f['cause']}: "), f["reading"]]
            + ([f" — {f['why_no_extension']}"] if f.get("why_no_extension") else [])
            for f in findings
        )
    fig, caption = beta_figure(res)
    doc.figure(fig, caption)
    if _dated(runs):
        fig, caption = day_figure(res)
        doc.figure(fig, caption)


def _extension(doc: Document, res: WheelValidation, disc: WheelDiscovery) -> None:
    """The slip-dependent exponent: its held-out gains, figure and where it still fails."""
    doc.heading("The extension: a slip-dependent exponent")
    doc.paragraph(
        "The normal stress of the wheel takes the exponent N = n + n1·s for s ≥ 0 and "
        "N = n + n2·|s| in skid, n the plates' exponent (so N = n at s = 0). The driving "
        "form is that of Ding, Gao, Deng and Tao (2010, J. Cent. South Univ. Technol. "
        "17(1)), used by Ding et al. (2011) and by the data's own authors; the skid branch "
        "is theirs. It stays inside the Wong–Reece stresses and has one coefficient per "
        "slip direction, fitted per wheel by least squares on the β = 0 runs; its gain is "
        "measured only on runs the fit did not see."
    )
    gains = pd.DataFrame([{"held out": k} | g.to_dict() for k, g in disc.gains.items()])
    gains["base (mm)"], gains["extended (mm)"] = gains["base"] * 1e3, gains["extended"] * 1e3
    gains["difference (mm)"] = gains["difference"] * 1e3
    gains["SE (mm)"] = gains["stderr"] * 1e3
    doc.table(
        gains[["held out", "folds", "n_tests", "base (mm)", "extended (mm)", "relative",
               "difference (mm)", "SE (mm)", "real"]],
        caption="Held-out gain: mean absolute sinkage error of β = 0 runs predicted by fits "
        "that never saw their slip condition (slip) or their day (day), per wheel and "
        "pooled; SE clustered by fold; real: difference > 2 SE.",
        labels={"n_tests": "runs"},
        formats={"relative": "+.0%", "base (mm)": ".2f", "extended (mm)": ".2f",
                 "difference (mm)": ".2f", "SE (mm)": ".2f"},
    )  # fmt: skip
    fig, caption = extension_figure(res)
    doc.figure(fig, caption)
    fails = pd.DataFrame(disc.still_fails)
    if len(fails):
        table = pd.DataFrame(
            {
                "wheel": fails["wheel"],
                "held out": fails["level"],
                "runs": fails["runs"],
                "measured (mm)": fails["measured_mean_m"] * 1e3,
                "error, plates (mm)": fails["base_mae_m"] * 1e3,
                "error, extended (mm)": fails["extended_mae_m"] * 1e3,
                "in band": fails["extended_coverage_90"],
            }
        )
        doc.table(
            table,
            caption="Where the extended model still fails: per slip condition held out "
            "(β = 0) and per slip angle (β ≠ 0 runs, never fitted), mean measured sinkage, "
            "mean absolute error before and after, share of runs in the extended band.",
            formats={c: ".1f" for c in table.columns if "(mm)" in c} | {"in band": ".0%"},
        )
    for note in disc.notes:
        doc.note(note)


def _sensitivity(doc: Document, res: WheelValidation) -> None:
    """Bekker's b and the exit angle: the runs near zero slip under other choices."""
    doc.heading("Sensitivity: Bekker's b and the exit angle")
    sens = pd.DataFrame(res.sensitivity)
    doc.table(
        pd.DataFrame(
            {
                "choice": sens["case"],
                "wheel": sens["wheel"],
                "law b (mm)": sens["law_b_m"] * 1e3,
                "measured (mm)": sens["measured_mean_m"] * 1e3,
                "predicted (mm)": sens["predicted_mean_m"] * 1e3,
                "modulus ≤ 0": sens["modulus_nonpositive"],
            }
        ),
        caption="The β = 0 runs near zero slip predicted under other choices (medians over "
        f"{int(sens['draws'].max())} draws). A rear contact behind the bottom is what the "
        "data's authors tuned on these runs; it is not measured here.",
        formats={"law b (mm)": ".0f", "measured (mm)": ".1f", "predicted (mm)": ".1f"},
        align_numbers=True,
    )


def _forces_and_caveats(
    doc: Document, res: WheelValidation, calibration: CalibrationReport | None
) -> None:
    """Drawbar pull (or why not predicted), the calibration, the caveats and notes."""
    if not res.unpredictable and "drawbar_pull_beta_0" in res.coverage:
        doc.heading("Drawbar pull with stated shear priors")
        fig, caption = drawbar_figure(res)
        doc.figure(fig, caption)
    elif res.unpredictable:
        doc.heading("Not predicted")
        doc.bullets([strong(f"{q}: "), reason] for q, reason in res.unpredictable.items())

    if calibration is not None:
        calibration_sections(doc, calibration)
    doc.heading("Caveats of the data and notes")
    doc.numbered([*res.caveats, *res.notes])
    for e in res.excluded:
        doc.paragraph(
            strong(f"Left out of the headline ({len(e['runs'])} runs): "),
            e["reason"] + " (the runs are listed in wheel.json, excluded).",
        )


def _dated(runs: pd.DataFrame) -> bool:
    """Whether any run has a date (a date cell neither missing nor empty)."""
    if "date" not in runs:
        return False
    return bool((runs["date"].notna() & runs["date"].astype(str).str.len().gt(0)).any())


class _Tests:
    """The residual tests alone, when the extension was not run."""

    def __init__(self, tests):
        self.tests = tests
