"""The wheel validation on the bundled CMU runs (docs/wheel.md, "Validation on measured runs").

    python docs/figures/wheel_validation.py

Runs ``soilstats wheel cmu-3d-terramechanics`` (seed 0) into a temporary folder and writes
docs/figures/wheel-validation.png — the report's Figure 1: every β = 0 run's measured sinkage
against slip with its predicted 90 % band from the plate tests and the held-out slip-exponent
median — and docs/figures/report-wheel.png, page 1 of wheel.pdf (poppler's pdftoppm).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from soilstats.cli.main import main as soilstats
from soilstats.data import bundled_path
from soilstats.report.document import render_page
from soilstats.report.wheel_figures import predicted_figure
from soilstats.wheel import validate_wheel

HERE = Path(__file__).resolve().parent
CMU = "cmu-3d-terramechanics"


def main() -> None:
    result = validate_wheel(CMU, bundled_path(CMU) / "wheel.csv", seed=0)
    fig, _ = predicted_figure(result)
    fig.savefig(HERE / "wheel-validation.png", dpi=130, metadata={"Software": None})
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "wheel"
        if soilstats(["wheel", CMU, "--out", str(out), "--progress", "off"]) != 0:
            raise SystemExit("soilstats wheel failed")
        print(render_page(out / "wheel.pdf", HERE / "report-wheel"))
    print(HERE / "wheel-validation.png")


if __name__ == "__main__":
    main()
