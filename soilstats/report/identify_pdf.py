"""The PDF report of ``soilstats identify``: parameters per soil and condition, and whether
each can be used.

Page 1 answers in a few sentences: how many parameter sets, which σ they carry (the
test-level σ where a set rests on five tests or more, Eq. 4's otherwise), how many carry
health flags and which. Then one figure per soil and kind (each condition's fitted curve with
its band), the paper's Tables 5 and 6 (value ± σ, Eq. 4's σ beside it), the methods with the
paper's equations, and one appendix table each for the health flags and for the notes (the
notes every fit shares printed once, numbered). Everything in identify.json is in the PDF.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from matplotlib import colormaps
from matplotlib.figure import Figure

from .._text import plural
from ..identification.table import EQ4_MARK
from ..outputs.files import output_path
from .document import Document, strong, tight_layout
from .front import data_origin, front_page
from .labels import natural_key
from .methods import write_equations
from .parameters import EQ4_NOTE, condition_table

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from ..campaign.campaign import Campaign
    from ..identification.conditions import ConditionFits
    from ..identification.result import CampaignFit
    from ..outputs.provenance import Provenance

__all__ = ["write_report"]


def condition_text(record: dict) -> str:
    """A condition in words: ``preparation = 1``, or ``all tests``."""
    condition = record.get("condition")
    if not condition:
        return "all tests"
    if isinstance(condition, dict):
        return f"{condition.get('column')} = {condition.get('value')}"
    return str(condition)


def _where(record: dict) -> str:
    parts = [record["soil"]]
    if record.get("series"):
        parts.append(f"series {record['series']}")
    parts.append(condition_text(record))
    return ", ".join(parts)


def _conclusion(records: list[dict], failures: int) -> list:
    n = len(records)
    tests_level = sum(d.get("stderr_level") == "tests" for d in records)
    codes = Counter(h["code"] for d in records for h in d["health"])
    clean = sum(not d["health"] for d in records)
    soils = sorted({d["soil"] for d in records}, key=natural_key)
    out: list = [
        [
            strong(f"{plural(n, 'parameter set')} of {plural(len(soils), 'soil')}"),
            f" ({', '.join(soils)}), identified by the paper's weighted Levenberg–Marquardt "
            "fit (Eq. 1). ",
            f"The ± of {tests_level} of them is the test-level σ — the sd over a bootstrap of "
            "their tests, what a new campaign of the same design would scatter by"
            + (
                f"; the other {n - tests_level} rest on fewer than five tests and carry Eq. 4's "
                f"σ (marked {EQ4_MARK}), which leaves the scatter between tests out."
                if n > tests_level
                else "."
            ),
        ],
        (
            [
                strong(f"{n - clean} of {n} sets carry health flags: "),
                ", ".join(f"{code} ({count})" for code, count in codes.most_common())
                + ". The table of flags at the end says what each means for its set; "
                "docs/identification.md says what to do.",
            ]
            if codes
            else [strong("No set carries a health flag: "), "each can be used as it is."]
        ),
    ]
    if failures:
        out.append(f"{plural(failures, 'condition')} could not be identified (listed at the end).")
    return out


def _soil_figure(soil: str, pairs: list) -> Figure:
    """One figure per soil: a panel per kind (sinkage, shear) with the measured samples as
    dots under every condition's fitted curve and its band (eval_uncertainty: the test-level
    band where the fit rests on five tests or more), over the depth or stress its data span;
    each panel's title says how far the conditions' curves lie apart mid-range."""
    kinds = list(dict.fromkeys(record["kind"] for record, _ in pairs))
    # A Figure of its own, not pyplot's: no backend is chosen for the caller (issue #45).
    fig = Figure(figsize=(6.4, 2.7))
    axes = fig.subplots(1, len(kinds), squeeze=False)
    for ax, kind in zip(axes[0], kinds, strict=True):
        mine = [(r, f) for r, f in pairs if r["kind"] == kind]
        series = list(dict.fromkeys(r.get("series") for r, _ in mine))
        cmap = colormaps["tab10"]
        middle = []
        label = ""
        for record, fit in mine:
            colour = cmap(series.index(record.get("series")) % 10)
            # A lone plate-size fit is drawn at each plate it rests on, several at the median.
            curves = _curve_inputs(kind, fit, every_plate=len(mine) == 1)
            label = curves[0][3] if curves else label
            for (x, grid, scale, _), style in zip(curves, ("-", "--", ":", "-."), strict=False):
                _measured_points(ax, fit, x, scale, colour)
                y, band = fit.eval(x), fit.eval_uncertainty(x)
                ax.plot(grid * scale, y / 1e3, color=colour, lw=0.8, ls=style)
                ax.fill_between(
                    grid * scale, (y - band) / 1e3, (y + band) / 1e3, color=colour, alpha=0.08
                )
                middle.append(float(y[grid.size // 2]))
        for i, name in enumerate(series):
            ax.plot([], [], color=cmap(i % 10), label=name or "all tests")
        ax.legend(fontsize=8, frameon=False)
        ax.set_xlabel(label, fontsize=8)
        ax.set_ylabel("p [kPa]" if kind == "sinkage" else "τ [kPa]", fontsize=8)
        ax.tick_params(labelsize=8)
        finding = f"{kind}: {plural(len(middle), 'curve')}"
        if len(mine) == 1 and len(middle) > 1 and min(middle) > 0:
            trend = "rises" if middle[-1] > middle[0] else "falls"  # plates narrow to wide
            finding = (
                f"{kind}: pressure {trend} {max(middle) / min(middle):.2g}× from the "
                "narrowest plate to the widest"
            )
        elif len(middle) > 1 and min(middle) > 0:
            finding += f" within a factor {max(middle) / min(middle):.2g} mid-range"
        ax.set_title(finding, fontsize=8)
    fig.suptitle(soil, fontsize=9)
    tight_layout(fig)
    return fig


#: Most measured points drawn under one curve (every k-th sample beyond: the figure shows
#: where the data lie, the JSON and CSV hold every value).
_MAX_POINTS = 400


def _measured_points(
    ax: Axes, fit: CampaignFit, x: np.ndarray, scale: float, colour: Any
) -> None:
    """The samples the fit was made on, as small dots under its curve: for a plate-size
    model only those of the plate the curve is drawn at."""
    if fit.x_data is None or fit.y_data is None:
        return
    xs, ys = np.asarray(fit.x_data, float), np.asarray(fit.y_data, float)
    if xs.ndim == 2:
        keep = np.isclose(xs[0], np.asarray(x)[0][0])
        xs, ys = xs[-1][keep], ys[keep]
    if xs.size == 0:
        return
    step = max(1, xs.size // _MAX_POINTS)
    ax.plot(
        xs[::step] * scale,
        ys[::step] / 1e3,
        ".",
        ms=1.5,
        color=colour,
        alpha=0.35,
        zorder=1,
        rasterized=True,
    )


def _curve_inputs(kind: str, fit: CampaignFit, *, every_plate: bool = False) -> list[tuple]:
    """[(x for ``fit.eval``, the grid plotted, its scale to display units, axis label)]: one
    curve, or for a plate-size model with ``every_plate`` one per plate width (at most four)."""
    tests = fit.tests
    if tests is None or fit.model_func is None:
        return []
    if kind == "sinkage":
        z_max = float(np.nanmax(tests["z_max_m"])) if "z_max_m" in tests else 0.03
        grid = np.linspace(z_max / 50, z_max, 60)
        if "b_m" in tests and fit.param_names[0] in ("kc", "k1"):
            unique = np.unique(tests["b_m"].to_numpy(dtype=float))
            plates: np.ndarray | list[float] = unique
            if not every_plate or unique.size > 4:
                plates = [float(np.median(tests["b_m"]))]
            sizes = ", ".join(f"{b * 1e3:.3g}" for b in plates)
            label = f"sinkage z [mm] (plate b = {sizes} mm: " + (
                "solid, dashed, …)" if len(plates) > 1 else "the median plate)"
            )
            return [(np.vstack([np.full(grid.size, b), grid]), grid, 1e3, label) for b in plates]
        return [(grid, grid, 1e3, "sinkage z [mm]")]
    if fit.param_names == ("c", "phi"):
        top = float(np.nanmax(tests["sigma_mean_Pa"])) if "sigma_mean_Pa" in tests else 2e4
        grid = np.linspace(0, top, 60)
        return [(grid, grid, 1e-3, "normal pressure σ [kPa]")]
    return []


def _condition(record: dict) -> dict:
    """An identify.json record as a row of :func:`condition_table`."""
    return {
        "condition": condition_text(record),
        "model": record["model"],
        "params": record["params"],
        "stderr": record["stderr"],
        "stderr_eq4": record.get("stderr_eq4"),
        "stderr_level": record.get("stderr_level"),
        "units": record["units"],
        "epsilon": record["epsilon"],
        "tests": record["tests"],
        "health": ", ".join(h["code"] for h in record["health"]) or "ok",
    }


def write_report(
    results: Iterable[ConditionFits],
    path: str | Path,
    *,
    campaign: Campaign,
    provenance: Provenance | None = None,
    overwrite: bool = False,
    defaults: Mapping[str, str] | None = None,
) -> int:
    """Write the typeset identification report of ``results`` (ConditionFits per kind) of
    ``campaign`` to ``path``.

    Returns the number of pages; an existing file is an error unless ``overwrite`` (the
    signature of every report writer: docs/conventions.md).
    """

    path = output_path(Path(path).parent, Path(path).name, overwrite=overwrite)
    pairs = [(f.to_dict(), f.fit) for r in results for f in r.fits]
    pairs.sort(
        key=lambda p: (p[0]["kind"], natural_key(p[0]["soil"]), natural_key(condition_text(p[0])))
    )
    records = [record for record, _ in pairs]
    failures = [f for r in results for f in r.failures]
    doc = Document(
        "Soil parameters identified from Bevameter tests",
        subtitle="soilstats identify — weighted Levenberg–Marquardt after Apfelbeck et al. (2011)",
        provenance=provenance,
    )
    kinds = tuple(dict.fromkeys(d["kind"] for d in records))
    front_page(
        doc,
        question=[
            "What are the soil parameters of each soil and test condition (Bekker k_c, k_φ, n or "
            "Bernstein k, n from plate sinkage; Mohr–Coulomb c, φ from shear), with what "
            "uncertainty, and can each set be trusted?"
        ],
        data=[
            data_origin(campaign.source),
            f": {len(campaign.tests)} tests; kinds identified: {', '.join(kinds)}.",
        ],
        conclusion=_conclusion(records, len(failures)),
        defaults=defaults,
    )
    doc.heading("Parameters per soil and condition")
    doc.note(
        f"In the tables: {EQ4_NOTE} ε: fit quality (Eq. 2). The paper's Tables 5 (sinkage) "
        "and 6 (shear) in this form."
    )
    for soil, mine in _by_soil(pairs).items():
        doc.heading(soil, level=2)
        doc.figure(
            _soil_figure(soil, mine),
            f"{soil}: the measured samples (dots; at most {_MAX_POINTS} per curve) under each "
            "condition's fitted curve with its one-σ band (the test-level band "
            "where the fit rests on five tests or more, Eq. 4's otherwise), coloured by series; "
            "a plate-size model at the plate widths named on its axis.",
        )
        for (kind, _, series, model), group in _groups(mine).items():
            where = f"{kind} / {soil}" + (f", series {series}" if series else "") + f" ({model})"
            condition_table(doc, [_condition(record) for record, _ in group], caption=where)
    doc.heading("Methods")
    write_equations(doc, kinds)
    _flags_and_notes(doc, records, failures, [n for r in results for n in r.notes])
    doc.provenance_section()
    return doc.render(path)


def _flags_and_notes(doc: Document, records: list[dict], failures: list, notes: list) -> None:
    """One appendix table of every health flag and one of every set's notes: a note two
    sets or more share is printed once, numbered, and referred to by its number; the method,
    screening and window are said once where every set shares them."""
    flags = [
        {"set": f"{d['kind']} / {_where(d)}", "code": h["code"], "message": h["message"]}
        for d in records
        for h in d["health"]
    ]
    doc.heading("Appendix: health flags")
    if flags:
        doc.table(
            pd.DataFrame(flags),
            caption="Every health flag of every parameter set (what to do: "
            "docs/identification.md).",
            align_numbers=False,
            small=True,
            widths=["26%", "auto", "1fr"],
        )
    else:
        doc.paragraph("No parameter set carries a health flag.")
    counts = Counter(note for d in records for note in dict.fromkeys(d["notes"]))
    shared = {note: k for k, note in enumerate((n for n in counts if counts[n] > 1), 1)}
    settings = {
        "method": [d["method"] for d in records],
        "screening": [d.get("quality") or "off" for d in records],
        "window": [_window_text(d.get("window")) for d in records],
    }
    common = {key: values[0] for key, values in settings.items() if len(set(values)) == 1}
    rows = []
    for i, d in enumerate(records):
        numbers = sorted({shared[n] for n in d["notes"] if n in shared})
        own = [n for n in d["notes"] if n not in shared]
        row = {
            "set": f"{d['kind']} / {_where(d)}",
            # each note a sentence of its own (they end in a full stop: no ".;")
            "notes": " ".join(
                ([f"[{', '.join(map(str, numbers))}]"] if numbers else [])
                + [n if n.endswith((".", "?", "!")) else n + "." for n in own]
            )
            or "–",
            "samples": d["nobs"],
        }
        row |= {key: values[i] for key, values in settings.items() if key not in common}
        if d.get("excluded"):
            said = "Excluded by screening: " + "; ".join(map(_excluded_text, d["excluded"]))
            row["notes"] = said if row["notes"] == "–" else f"{row['notes']} {said}"
        rows.append(row)
    frame = pd.DataFrame(rows)
    wide = {"set": "22%", "notes": "1fr", "method": "16%"}
    doc.heading("Appendix: notes")
    if shared:
        doc.paragraph("Notes shared by several parameter sets:")
        doc.numbered(list(shared), small=True)
    said = "; ".join(f"{key} {value}" for key, value in common.items())
    doc.table(
        frame,
        caption="The notes of each parameter set ([numbers] of the list above, then its own)"
        + (f"; every set: {said}." if said else "."),
        formats={"samples": ".0f"},
        align_numbers=False,
        small=True,
        widths=[wide.get(c, "auto") for c in frame.columns],
    )
    if failures or notes:
        doc.heading("Conditions not identified and notes")
        doc.numbered([*failures, *notes], small=True)


def _window_text(window: dict | None) -> str:
    """``radius_m = 0.038: z ≤ 3.4 mm (53 samples beyond)`` from an identify.json ``window``
    record (its rules and the samples each test had outside them); ``none`` without one."""
    if not window:
        return "none"
    rules = []
    for rule in window.get("rules") or []:
        limits = []
        if rule.get("z_max_m") is not None:
            limits.append(f"z ≤ {1e3 * rule['z_max_m']:.4g} mm")
        if rule.get("p_max_Pa") is not None:
            limits.append(f"p ≤ {1e-3 * rule['p_max_Pa']:.4g} kPa")
        where = f"{rule['column']} = {rule['value']}: " if rule.get("column") else ""
        rules.append(where + (" and ".join(limits) or "no limit"))
    outside = sum((window.get("outside") or {}).values())
    beyond = f" ({plural(outside, 'sample')} beyond)" if outside else ""
    return "; ".join(rules or ["none"]) + beyond


def _excluded_text(entry: object) -> str:
    """``method1-test3 unload-reload: 60 samples (rows 6291–6350)`` from an identify.json
    ``excluded`` entry (test, screening code, data-file rows)."""
    if not isinstance(entry, dict):
        return str(entry)
    rows = entry.get("rows") or []
    span = ""
    if rows:
        within = "" if max(rows) - min(rows) + 1 == len(set(rows)) else "within "
        span = f" ({within}rows {min(rows)}–{max(rows)})"
    return f"{entry.get('test_id')} {entry.get('code')} {plural(len(rows), 'sample')}{span}"


def _by_soil(pairs: list) -> dict[str, list]:
    out: dict[str, list] = {}
    for record, fit in pairs:
        out.setdefault(record["soil"], []).append((record, fit))
    return out


def _groups(pairs: list) -> dict[tuple, list]:
    out: dict[tuple, list] = {}
    for record, fit in pairs:
        key = (record["kind"], record["soil"], record.get("series"), record["model"])
        out.setdefault(key, []).append((record, fit))
    return out
