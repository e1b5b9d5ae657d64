"""Loop over soilstats' Chrono SCM parameter sets: one SCM soil per posterior draw.

Reads ``chrono-scm.csv`` and its record ``chrono-scm.json`` (written by ``soilstats posterior
... --simulator chrono-scm --out DIR``) and, for each row, makes the call
``SCMTerrain::SetSoilParameters(Bekker_Kphi, Bekker_Kc, Bekker_n, Mohr_cohesion,
Mohr_friction, Janosi_shear, elastic_K, damping_R)`` — printed, and made on a real
``pychrono.vehicle.SCMTerrain`` when pychrono is installed. A rover Monte Carlo runs one
simulation per row (where ``simulate`` is called below); the rows are in random order, so any
first N rows are a fair sample.

Every row is checked against SCM's own rule elastic_K > Bekker_Kphi before the call: Chrono
would silently raise elastic_K to Bekker_Kphi (SCMTerrain.cpp, SetSoilParameters), so a row
that breaks it (a file written with --force) is skipped and counted, never passed on.

Standard library only::

    python examples/chrono_scm_loop.py DIR [--rows N]
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path


def read_export(folder: Path) -> tuple[dict, list[dict[str, float]]]:
    """The JSON record and the CSV rows (``#`` lines are the provenance and the sources).
    The record's ``arguments`` are SetSoilParameters' arguments in order."""
    record = json.loads((folder / "chrono-scm.json").read_text(encoding="utf-8"))
    with open(folder / "chrono-scm.csv", newline="", encoding="utf-8") as handle:
        lines = (line for line in handle if not line.startswith("#"))
        rows = [{k: float(v) for k, v in row.items()} for row in csv.DictReader(lines)]
    missing = [name for name in record["arguments"] if rows and name not in rows[0]]
    if missing:
        raise SystemExit(f"chrono-scm.csv lacks the columns {missing}")
    return record, rows


def scm_terrain():
    """A pychrono SCM terrain to call, or None when pychrono is not installed."""
    try:
        import pychrono as chrono
        import pychrono.vehicle as veh
    except ImportError:
        return None
    system = chrono.ChSystemSMC()
    terrain = veh.SCMTerrain(system)
    terrain.Initialize(2.0, 2.0, 0.02)  # a 2 m x 2 m patch, 2 cm grid
    return terrain


def simulate(terrain) -> None:
    """Where one run of the rover model on this soil goes (left to the user)."""


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path, help="the --out folder of soilstats posterior")
    parser.add_argument("--rows", type=int, default=10, help="rows to use (0: every row)")
    args = parser.parse_args(argv)

    record, rows = read_export(args.folder)
    print(f"{len(rows)} parameter sets for {record['call']}")
    for column, source in record["sources"].items():
        print(f"  {column} [{record['columns'][column]}]: {source}")
    for note in record.get("notes", []):
        print(f"  note: {note}")
    if record.get("forced"):
        print("WARNING: FORCED export: " + "; ".join(record.get("failures", [])), file=sys.stderr)

    terrain = scm_terrain()
    print(
        "pychrono: "
        + ("not installed" if terrain is None else "calling SCMTerrain.SetSoilParameters")
    )
    chosen = rows if args.rows <= 0 else rows[: args.rows]
    skipped = 0
    for i, row in enumerate(chosen):
        values = [row[name] for name in record["arguments"]]
        if not row["elastic_K"] > row["Bekker_Kphi"]:
            skipped += 1  # Chrono would raise elastic_K silently: never pass such a row on
            kphi, elastic = row["Bekker_Kphi"], row["elastic_K"]
            print(f"row {i}: SKIPPED, elastic_K <= Bekker_Kphi ({elastic:.6g} <= {kphi:.6g})")
            continue
        repaired = "  # elastic_K repaired" if row.get("elastic_K_repaired") else ""
        print(f"row {i}: SetSoilParameters({', '.join(f'{v:.6g}' for v in values)}){repaired}")
        if terrain is not None:
            terrain.SetSoilParameters(*values)
            simulate(terrain)
    print(f"{len(chosen) - skipped} of {len(chosen)} rows used ({len(rows)} in the file)")
    if skipped:
        print(
            f"WARNING: {skipped} rows skipped: they break elastic_K > Bekker_Kphi", file=sys.stderr
        )
    return 1 if skipped else 0


if __name__ == "__main__":
    sys.exit(main())
