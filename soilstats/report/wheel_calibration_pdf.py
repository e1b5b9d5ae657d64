"""The calibration part of the wheel report (``soilstats wheel --calibrate``).

Page 1 gets the held-out answer in sentences with numbers — coverage, width and MAE on slip
conditions the calibration never saw, interpolated and extrapolated apart, beside the
no-physics baseline, the wheel transfer, and every missed target said plainly; the body gets
the calibrated inputs with their priors and sources, the discrepancy, the offset budget at
zero slip, the held-out tables by slip and a figure of the held-out bands.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import matplotlib.pyplot as plt
import pandas as pd

from .document import Document, strong

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ..wheel.calibration.validate import CalibrationReport

__all__ = ["calibration_conclusion", "calibration_sections"]

_LABEL = {
    "sinkage": ("sinkage", 1e3, "mm"),
    "drawbar_pull": ("drawbar pull", 1.0, "N"),
    "lateral_force": ("lateral force", 1.0, "N"),
}


def _cov(s: dict, name: str) -> str:
    _, scale, unit = _LABEL[name]
    key = "m" if unit == "mm" else "N"
    return (
        f"{s['covered']}/{s['runs']} ({s['coverage_90']:.0%}) at a median width of "
        f"{scale * s[f'median_width_{key}']:.1f} {unit}, MAE {scale * s[f'mae_{key}']:.1f} "
        f"{unit}"
    )


def calibration_conclusion(report: CalibrationReport) -> list:
    """Page-1 paragraphs of the calibration: held-out answers and missed targets."""
    held = report.held_out
    out: list = []
    slip = held.get("slip_condition", {})
    base = held.get("baseline", {})
    if "sinkage" in slip:
        s = slip["sinkage"]
        b = base.get("sinkage", {}).get("beta_0", {})
        text = (
            "calibrated on the wheel runs with a model-discrepancy term and tested on slip "
            "conditions it never saw (every repeat of a slip left out together), the 90 % band "
            f"holds {_cov(s['beta_0'], 'sinkage')} of sinkage at β = 0"
        )
        if b:
            text += f"; the no-physics baseline's MAE is {1e3 * b['mae_m']:.1f} mm"
        if s.get("interpolated", {}).get("runs") and s.get("extrapolated", {}).get("runs"):
            inside = _cov(s["interpolated"], "sinkage")
            beyond = _cov(s["extrapolated"], "sinkage")
            text += (
                f". Inside the range of the calibrated slips: {inside}; beyond it "
                f"(extrapolated, e.g. the locked wheel): {beyond}"
            )
        out.append([strong("Calibrated, held out by slip: "), text + "."])
    if "drawbar_pull" in slip:
        out[-1].append(f" Drawbar pull: {_cov(slip['drawbar_pull']['beta_0'], 'drawbar_pull')}.")
    transfer = held.get("wheel_transfer", {})
    if transfer:
        parts = [
            f"{label}: {_cov(block['sinkage']['all_runs'], 'sinkage')}"
            for label, block in transfer.items()
            if "sinkage" in block
        ]
        out.append(
            [
                strong("A new wheel: "),
                "calibrated on one wheel type and predicting the "
                "other, sinkage " + "; ".join(parts) + ".",
            ]
        )
    missed = report.missed
    if missed:
        out.append([strong("Targets missed: "), "; ".join(t["text"] for t in missed) + "."])
    elif report.targets:
        out.append([strong("Targets: "), "every target of the held-out validation is met."])
    if not report.calibration.converged:
        out.append(
            [
                strong("The calibration did not converge: "),
                "; ".join(report.calibration.flags) + ".",
            ]
        )
    return out


def _heldout_figure(report: CalibrationReport) -> tuple[Figure, str]:
    frame = report.heldout
    f = frame[frame["scheme"] == "slip_condition"]
    wheels = sorted(set(f["wheel"]))
    fig, axes = plt.subplots(1, len(wheels), figsize=(6.5, 2.8), sharey=True, squeeze=False)
    for ax, wheel in zip(axes[0], wheels, strict=True):
        rows = f[f["wheel"] == wheel].sort_values("slip")
        ax.errorbar(
            rows["slip"],
            1e3 * rows["sinkage_m_median"],
            yerr=[
                1e3 * (rows["sinkage_m_median"] - rows["sinkage_m_lower"]),
                1e3 * (rows["sinkage_m_upper"] - rows["sinkage_m_median"]),
            ],
            fmt="o",
            ms=3,
            color="C0",
            alpha=0.6,
            label="held-out band (90 %)",
        )
        ax.plot(
            rows["slip"], 1e3 * rows["sinkage_m_measured"], "x", color="k", ms=4, label="measured"
        )
        ax.set_title(f"{wheel} wheel, β = 0", fontsize=9)
        ax.set_xlabel("slip s")
    axes[0][0].set_ylabel("sinkage [mm]")
    axes[0][0].legend(fontsize=8, loc="upper center")  # 8 pt: the smallest a report prints
    fig.tight_layout()
    caption = (
        "Sinkage of each β = 0 run predicted by a calibration that never saw its slip "
        "condition (median and 90 % band), against the measured sinkage."
    )
    return fig, caption


def _scheme_rows(report: CalibrationReport) -> list[list]:
    rows = []
    held = report.held_out
    for scheme in ("slip_condition", "slip_angle", "baseline"):
        for name, scopes in held.get(scheme, {}).items():
            label, scale, unit = _LABEL[name]
            key = "m" if unit == "mm" else "N"
            for scope in ("beta_0", "interpolated", "extrapolated"):
                s = scopes.get(scope, {})
                if not s.get("runs"):
                    continue
                rows.append(
                    [
                        scheme.replace("_", " "),
                        label,
                        scope.replace("_", " "),
                        s["runs"],
                        f"{s['coverage_90']:.0%}" if "coverage_90" in s else "–",
                        f"{scale * s[f'median_width_{key}']:.1f}" if "covered" in s else "–",
                        f"{scale * s[f'mae_{key}']:.2f}",
                        f"{scale * s[f'bias_{key}']:+.2f}",
                        unit,
                    ]
                )
    for label_t, block in held.get("wheel_transfer", {}).items():
        for name, scopes in block.items():
            label, scale, unit = _LABEL[name]
            key = "m" if unit == "mm" else "N"
            s = scopes["all_runs"]
            rows.append(
                [
                    f"wheel {label_t}",
                    label,
                    "all",
                    s["runs"],
                    f"{s['coverage_90']:.0%}",
                    f"{scale * s[f'median_width_{key}']:.1f}",
                    f"{scale * s[f'mae_{key}']:.2f}",
                    f"{scale * s[f'bias_{key}']:+.2f}",
                    unit,
                ]
            )
    return rows


def _table(doc: Document, columns: list[str], rows: list[list], caption: str) -> None:
    doc.table(pd.DataFrame(rows, columns=columns), caption=caption, align_numbers=False)


def calibration_sections(doc: Document, report: CalibrationReport) -> None:
    """The calibration's sections of the wheel report."""
    cal = report.calibration
    doc.heading("Calibration on the wheel runs")
    doc.paragraph(
        f"The wheel-level inputs and the plate law (prior: {cal.layout.plate.source}) were "
        f"sampled with emcee on {len(cal.design)} runs, with a Gaussian-process discrepancy in "
        "slip and slip angle (Kennedy & O'Hagan 2001) integrated out; R-hat "
        f"{cal.rhat_max:.3f}, bulk ESS {cal.ess_min:.0f}"
        + ("." if cal.converged else f" — NOT CONVERGED ({'; '.join(cal.flags)}).")
    )
    table = cal.parameter_table().reset_index()
    priors = {p.name: p for p in cal.layout.inputs}
    rows = []
    for r in table.itertuples():
        key = {"c": "c_kPa", "K": "log_K", "datum": "datum_mm"}.get(r.name, r.name)  # type: ignore[arg-type, misc]  # pandas-stubs: an itertuples field is any scalar
        prior = priors.get(key)  # type: ignore[arg-type]  # pandas-stubs: as above (a parameter name)
        rows.append(
            [
                r.name,
                r.unit,
                f"{r.mean:.4g}",
                f"{r.sd:.3g}",
                f"{r.q05:.4g}",
                f"{r.q95:.4g}",
                prior.describe() if prior else "plate posterior",
            ]
        )
    _table(
        doc,
        ["input", "unit", "mean", "sd", "5 %", "95 %", "prior"],
        rows,
        caption="Calibrated inputs (posterior) and their stated priors; sources in docs/wheel.md.",
    )
    _table(
        doc,
        ["quantity", "amplitude τ", "slip length", "β length (deg)", "repeat σ", "wheel τ_w"],
        [
            [
                q,
                f"{d.amplitude:.3g}",
                f"{d.length_slip:.2f}",
                f"{d.length_beta_deg:.0f}",
                f"{d.noise:.3g}",
                f"{d.wheel_amplitude:.3g}",
            ]
            for q, d in cal.discrepancy.items()
        ],
        caption="The discrepancy's hyperparameters (SI units): type-II maximum likelihood at "
        "the least-squares start; σ measured from the repeated runs.",
    )
    if report.offset:
        _table(
            doc,
            ["input", "absorbs (mm)", "share"],
            [
                [r["input"], f"{1e3 * r['absorbed_m']:+.2f}", f"{100 * r['share']:+.0f} %"]
                for r in report.offset
            ],
            caption="The plate-only model's mean sinkage error at s ≈ 0, β = 0 (first row), "
            "and how much of it each input absorbs when it alone takes its calibrated value; "
            "the last row is what the calibrated model leaves to the discrepancy.",
        )
    doc.heading("Held-out validation")
    _table(
        doc,
        ["scheme", "quantity", "scope", "runs", "coverage", "width", "MAE", "bias", "unit"],
        _scheme_rows(report),
        caption="Every held-out run is predicted by a calibration that never saw it. "
        "interpolated / extrapolated: the held-out slip inside / outside the calibrated range. "
        "baseline: no physics, residuals interpolated across slip.",
    )
    fig, caption = _heldout_figure(report)
    doc.figure(fig, caption)
    doc.numbered(report.notes)
