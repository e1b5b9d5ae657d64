"""Text overview of a campaign (:meth:`Campaign.summary`)."""

from __future__ import annotations

import numpy as np
import pandas as pd
from pandas.api.types import is_numeric_dtype

from .schema import KINDS
from .tables import CampaignTables

__all__ = ["describe"]

_UNITS = {
    "z_m": "m",
    "force_N": "N",
    "pressure_Pa": "Pa",
    "angle_rad": "rad",
    "torque_Nm": "N m",
    "normal_force_N": "N",
    "sigma_Pa": "Pa",
    "tau_Pa": "Pa",
    "j_m": "m",
}


def _range(series: pd.Series) -> str:
    v = series.to_numpy(dtype=np.float64, na_value=np.nan)
    unit = _UNITS.get(str(series.name), "")
    return f"{series.name} {np.nanmin(v):.4g} … {np.nanmax(v):.4g} {unit}".rstrip()


def _covariate(tests: pd.DataFrame, col: str) -> str:
    s = tests[col]
    kind = "numeric" if is_numeric_dtype(s.dtype) else "text"
    return f"{col} ({kind}, {int(s.notna().sum())} of {len(s)} recorded)"


def _samples(kind: str, table: pd.DataFrame, notes: list[str]) -> list[str]:
    if table.empty:
        return [f"{kind} samples: none"]
    per = table.groupby("test_id", sort=False).size()
    lines = [
        f"{kind} samples: {len(table)} row{'s' * (len(table) != 1)}, "
        f"{per.min()}–{per.max()} per test",
        "  ranges: " + "; ".join(_range(table[col]) for col in table.columns if col in _UNITS),
    ]
    if kind == "sinkage":
        first = table.groupby("test_id", sort=False)["z_m"].first()
        lines.append(f"  first reading per test: z_m {first.min():.4g} … {first.max():.4g} m")
        n_z = int((table["z_m"] <= 0).sum())
        n_p = int((table["pressure_Pa"] <= 0).sum())
        notes.append(
            f"Sinkage readings are kept as measured: {n_z} rows with z ≤ 0 and {n_p} with "
            "p ≤ 0 (sensor zero offsets); each fitting method states how it treats them."
        )
    return lines


def describe(c: CampaignTables) -> str:
    """Return the readable overview of campaign ``c`` (see :meth:`Campaign.summary`; typed by
    the protocol :class:`~soilstats.campaign.tables.CampaignTables`, so that this module need
    not import the one that imports it).

    Lists the tests per kind and soil, the log's columns and covariates (with how many tests
    record each), the sample counts and value ranges [SI units], the plates and rings, and the
    skipped tests; ends with numbered notes.
    """
    t = c.tests
    kinds = t["kind"].value_counts()
    lines = [
        f"Campaign {c.source}",
        f"tests: {len(t)} (" + ", ".join(f"{k} {int(kinds.get(k, 0))}" for k in KINDS) + ")",
    ]
    for soil, group in t.groupby("soil", sort=False):
        counts = group["kind"].value_counts()
        per = ", ".join(f"{k} {int(counts.get(k, 0))}" for k in KINDS)
        lines.append(f"  soil {soil!r}: {per}")
    sink = t[t["kind"] == "sinkage"]
    if len(sink):
        plates = sink.groupby(["shape", "b_m", "aspect_ratio"], sort=True).size()
        lines.append(
            "plates: "
            + ", ".join(f"{s} b={b:.4g} m l/w={a:.3g} (×{n})" for (s, b, a), n in plates.items())  # type: ignore[has-type, misc]  # pandas-stubs: a multi-column value_counts key is a tuple
        )
    shear = t[t["kind"] == "shear"]
    if len(shear):
        rings = shear.groupby(["r_inner_m", "r_outer_m", "grousers"], sort=True).size()
        lines.append(
            "rings: "
            + ", ".join(
                f"r {ri:.4g}–{ro:.4g} m, {g:g} grousers (×{n})" for (ri, ro, g), n in rings.items()  # type: ignore[has-type, misc]  # pandas-stubs: a multi-column value_counts key is a tuple
            )
        )
    lines.append("log columns: " + ", ".join(map(str, t.columns)))
    covs = c.covariates
    lines.append("covariates: " + (", ".join(_covariate(t, col) for col in covs) or "none"))
    notes: list[str] = []
    lines += _samples("sinkage", c.sinkage, notes)
    lines += _samples("shear", c.shear, notes)
    if c.skipped.empty:
        lines.append("skipped tests: none")
    else:
        lines.append(f"skipped tests: {len(c.skipped)}")
        lines += [
            f"  {r.test_id!r} ({r.file}, {r.column}): {r.reason}" for r in c.skipped.itertuples()
        ]
        notes.append("Skipped tests were dropped with all their samples (on_error='skip').")
    notes.append("Empty cells in optional and covariate columns are missing (NaN), never zero.")
    lines.append("Notes:")
    lines += [f"[{i}] {n}" for i, n in enumerate(notes, start=1)]
    return "\n".join(lines)
