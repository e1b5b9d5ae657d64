"""The PDF of ``soilstats wheel --predict``: a rover team's own wheel against slip.

Page 1: the wheel, the load and the answer — the slip beyond which the wheel is likely to
stall (P(drawbar pull < 0)), the slip needed for the requested pull with its band, and what the
band holds (calibrated with a discrepancy term, or parameter uncertainty only, said plainly);
the figure of the bands against slip.  Then the table of bands and the sources of every input.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib.pyplot as plt
import pandas as pd

from ..outputs.files import output_path
from .document import Document, strong
from .front import data_origin, front_page

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ..outputs.provenance import Provenance
    from ..wheel.calibration.predict import OwnWheelPrediction

__all__ = ["write_report"]

_SCALE = {
    "sinkage_m": (1e3, "sinkage [mm]"),
    "drawbar_pull_N": (1.0, "drawbar pull [N]"),
    "torque_Nm": (1.0, "torque [N·m]"),
    "lateral_force_N": (1.0, "lateral force [N]"),
}


def _figure(pred: OwnWheelPrediction) -> tuple[Figure, str]:
    quantities = list(dict.fromkeys(pred.bands["quantity"]))
    fig, axes = plt.subplots(1, len(quantities), figsize=(6.5, 2.6), squeeze=False)
    for ax, q in zip(axes[0], quantities, strict=True):
        scale, label = _SCALE[q]
        rows = pred.bands[pred.bands["quantity"] == q]
        ax.fill_between(
            rows["slip"],
            scale * rows["lower"],
            scale * rows["upper"],
            alpha=0.3,
            color="C0",
            label="90 % band",
        )
        ax.plot(rows["slip"], scale * rows["median"], color="C0", label="median")
        if q == "drawbar_pull_N":
            ax.axhline(0.0, color="k", lw=0.6)
        ax.set_xlabel("slip s")
        ax.set_ylabel(label)
    axes[0][0].legend(fontsize=8)  # 8 pt: the smallest a report prints
    fig.tight_layout()
    return fig, f"Predicted bands against slip at W = {pred.load_N:g} N ({pred.band_kind})."


def _conclusion(pred: OwnWheelPrediction) -> list:
    out: list = [[strong("What the band holds: "), pred.band_kind + "."]]
    stall = pred.p_drawbar_pull_negative
    if len(stall):
        drive = stall[stall["slip"] >= 0]
        likely = drive[drive["p"] < 0.5]
        text = (
            (
                "at every driving slip of the grid the wheel more likely pushes than pulls "
                "(P(drawbar pull < 0) ≥ 0.5)"
            )
            if likely.empty
            else (
                f"P(drawbar pull < 0) falls below 0.5 at s = {likely['slip'].min():.2f}; "
                f"its smallest value is {drive['p'].min():.2f} at s = "
                f"{drive.loc[drive['p'].idxmin(), 'slip']:.2f}"  # type: ignore[index]  # pandas-stubs: idxmin is a Hashable label
            )
        )
        out.append([strong("Stall: "), text + "."])
    if pred.slip_for_pull:
        s = pred.slip_for_pull
        out.append(
            [
                strong(f"Slip for {s['pull_N']:g} N of pull: "),
                f"median {s['median']:.3g}, 90 % band {s['lower']:.3g}–{s['upper']:.3g}; "
                f"{100 * s['p_unreachable']:.0f} % of draws never reach it on the grid.",
            ]
        )
    out += [[n] for n in pred.notes]
    return out


def write_report(
    pred: OwnWheelPrediction,
    path: str | Path,
    *,
    provenance: Provenance | None = None,
    overwrite: bool = False,
) -> int:
    """Write the typeset prediction report of ``pred`` to ``path``; return its pages."""
    path = output_path(Path(path).parent, Path(path).name, overwrite=overwrite)
    doc = Document(
        "How will this wheel perform on this soil?",
        subtitle="soilstats wheel --predict — Wong–Reece rigid wheel",
        provenance=provenance,
    )
    source = provenance.campaign if provenance is not None else ""
    front_page(
        doc,
        question=[
            f"For the wheel {pred.wheel.describe()} at a load of {pred.load_N:g} N and "
            f"slip angle {pred.slip_angle_deg:g}°: sinkage, drawbar pull and torque "
            "against slip, and where the wheel stalls."
        ],
        data=[data_origin(source) if source else "data passed in memory"],
        conclusion=_conclusion(pred),
    )
    fig, caption = _figure(pred)
    doc.figure(fig, caption)
    doc.page_break()
    doc.heading("Bands")
    doc.table(
        pred.bands,
        caption="Median and 90 % band per slip (SI units); not_carried: "
        "share of draws whose soil cannot carry the load.",
    )
    doc.heading("Sources")
    doc.table(
        pd.DataFrame(list(pred.sources.items()), columns=["input", "source"]),
        caption="Where every input of the prediction comes from.",
        align_numbers=False,
    )
    doc.provenance_section()
    return doc.render(path)
