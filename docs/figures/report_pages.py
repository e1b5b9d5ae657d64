"""Page 1 of each report type, as PNG pictures for the docs and the README.

    python docs/figures/report_pages.py

Runs each command into a temporary folder and renders page 1 of its PDF with poppler's
pdftoppm (Debian: poppler-utils) into docs/figures/report-<name>.png.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from soilstats.cli.main import main
from soilstats.report.document import render_page

HERE = Path(__file__).parent
COMMANDS = {
    "study": (["study", "velocity"], "velocity.pdf"),
    "discover": (["discover", "--data", "grc1-oravec2009"], "discover.pdf"),
    "check": (["check", "--data", "grc1-oravec2009"], "check.pdf"),
    "identify": (["identify", "--data", "grc1-oravec2009"], "identify.pdf"),
    "posterior": (
        [
            "posterior",
            "--data",
            "grc1-oravec2009",
            "--soil",
            "GRC-1",
            "--model",
            "bernstein",
            "--select",
            "sinkage:b_m=0.095",
        ],
        "report.pdf",
    ),
}


def render(name: str, argv: list[str], pdf: str, tmp: Path) -> Path:
    out = tmp / name
    code = main([*argv, "--out", str(out), "--progress", "off"])
    if code != 0:
        raise SystemExit(f"{name}: soilstats {' '.join(argv)} exited with {code}")
    return render_page(out / pdf, HERE / f"report-{name}")


if __name__ == "__main__":
    wanted = sys.argv[1:] or list(COMMANDS)
    with tempfile.TemporaryDirectory() as tmp:
        for name in wanted:
            argv, pdf = COMMANDS[name]
            print(render(name, argv, pdf, Path(tmp)))
