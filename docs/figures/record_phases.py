"""The phases soilstats finds in real plate records (docs/quality.md, "Phases of a record").

    python docs/figures/record_phases.py

Screens the bundled CMU and Cullinan campaigns and draws four records force against sinkage,
every sample coloured by the phase ``soilstats check`` names for it; writes
docs/figures/record-phases.png.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from soilstats.campaign import load_campaign
from soilstats.quality import screen

HERE = Path(__file__).resolve().parent
RECORDS = [
    ("cmu-3d-terramechanics", "small-D100-1", "CMU sand, 100 mm plate: a hold, then the release"),
    ("cullinan-sand", "method1-test3", "Cullinan, loose: unload to 12 N at 18 mm, reload"),
    ("cullinan-sand", "method2-test2", "Cullinan: a hold relaxing 7.7 %, then reload"),
    ("cullinan-sand", "method3-test1", "Cullinan, dense: a hold at 12 mm, a step at 72 mm"),
]
COLOURS = {
    "approach": "#bbbbbb",
    "contact": "#8c564b",
    "loading": "#1f77b4",
    "hold": "#ff7f0e",
    "unload": "#d62728",
    "reload": "#9467bd",
    "step": "#e377c2",
    "release": "#2ca02c",
    "failure": "#000000",
}


def main() -> None:
    fig, axes = plt.subplots(2, 2, figsize=(10, 7.5))
    for ax, (name, test_id, title) in zip(axes.flat, RECORDS, strict=True):
        campaign = load_campaign(name)
        report = screen(campaign)
        sink = campaign.sinkage
        rows = sink.index.to_numpy() + 1
        mine = (sink["test_id"] == test_id).to_numpy()
        z = sink["z_m"].to_numpy()[mine] * 1e3
        force = sink["force_N"].to_numpy()[mine]
        phase = np.full(mine.sum(), "", dtype=object)
        rows = rows[mine]
        for span in report.phases[test_id].spans:
            phase[(rows >= span.rows[0]) & (rows <= span.rows[1])] = span.phase
        for name_, colour in COLOURS.items():
            at = phase == name_
            if at.any():
                ax.plot(z[at], force[at], ".", ms=2.5, color=colour, label=name_)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("sinkage z [mm]")
        ax.set_ylabel("force [N]")
        ax.set_xlim(left=max(-2.0, float(z.min())))
        ax.legend(fontsize=7, markerscale=3, loc="upper left")
    fig.suptitle("Phases of real plate records, as soilstats check names them", fontsize=11)
    fig.tight_layout()
    fig.savefig(HERE / "record-phases.png", dpi=110)


if __name__ == "__main__":
    main()
