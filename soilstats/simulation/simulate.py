"""``simulate``: a campaign in the campaign format from known soil parameters, with its truth.

Random numbers come only from ``numpy.random.default_rng(seed)``, split into two independent
streams (parameters, noise) so that switching a noise source off leaves every test's drawn
parameters unchanged.  The same SPEC and seed give byte-identical files.
"""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .._version import __version__
from ..campaign import Campaign
from ..models.shear import side_wall_ratio
from ..outputs.files import csv_text, output_path, write_atomic
from .artefacts import plant
from .design import draw_parameters, expand, operator_biases
from .effects import apparent_shear, side_wall_K0, softening_of
from .records import SHEAR_PARAMS, SINKAGE_PARAMS, Series, Spec, SpecError
from .shear import shear_samples
from .sinkage import quantise, sinkage_samples
from .spec import load_spec, parse_spec
from .support import outside_support

__all__ = ["SimulatedCampaign", "simulate"]

_LOG_ORDER = (
    "test_id",
    "kind",
    "soil",
    "preparation",
    "operator",
    "repetition",
    "shape",
    "radius_m",
    "width_m",
    "length_m",
    "velocity_m_s",
    "r_inner_m",
    "r_outer_m",
    "grousers",
    "grouser_height_m",
    "omega_rpm",
    "series",
)
_PRIVATE = ("b_m", "area_m2", "aspect_ratio", "normal_pressure_Pa")
_ARTEFACT_COLUMNS = ("test_id", "kind", "first_row", "last_row", "samples", "rows")


@dataclass(frozen=True, eq=False)
class SimulatedCampaign:
    """A simulated campaign and the truth it was drawn from.

    Attributes
    ----------
    campaign : Campaign
        The data, exactly as :func:`soilstats.load_campaign` reads it back after :meth:`save`.
    truth : dict
        Per-soil parameters (with condition overrides), planted effects, preparation scatter
        and operator biases, noise levels, resolution, the SPEC's name, file and SHA-256, and
        the seed.  Units: kc N/m^(n+1), kphi N/m^(n+2), n -, c Pa, phi deg, K m.
    test_truth : DataFrame
        One row per test: the drawn parameters (``kc, kphi, n, c, phi, K``), the soil-level
        values for that test's condition after effects and before scatter (``*_soil``), the
        scatter factor, the operator bias, and for shear tests the set-point
        ``normal_pressure_Pa``, the per-test zero offsets (``force_offset_N``,
        ``torque_offset_Nm``), and the apparent Mohr–Coulomb values that Eq. 12 + Eq. 15
        report when side walls act (``c_apparent_Pa``, ``phi_apparent_deg``, drawn;
        ``c_apparent_soil``, ``phi_apparent_soil``, soil level).
    spec : Spec
    seed : int
    artefacts : DataFrame
        One row per planted record phase or glitch (``[[artefacts]]``): ``test_id``,
        ``kind``, ``first_row`` and ``last_row`` (1-based data rows of sinkage.csv),
        ``samples`` and ``rows`` (every row it concerns, space-separated); empty when the
        SPEC plants none.
    """

    campaign: Campaign
    truth: dict[str, Any]
    test_truth: pd.DataFrame
    spec: Spec
    seed: int
    artefacts: pd.DataFrame = dataclasses.field(
        default_factory=lambda: pd.DataFrame(columns=list(_ARTEFACT_COLUMNS))
    )

    def save(self, path: str | os.PathLike[str], *, overwrite: bool = False) -> Path:
        """Write the campaign files plus ``truth.json``, ``truth_tests.csv`` and ``README.md``.

        Parameters
        ----------
        path : str or os.PathLike
            Folder (created if needed).  Other files in it (e.g. the SPEC) are left alone.
        overwrite : bool
            Replace existing campaign and truth files.

        Returns
        -------
        Path
            The folder.
        """
        folder = Path(path)
        own = ("truth.json", "truth_tests.csv", "README.md")
        if not overwrite and any(os.path.lexists(folder / n) for n in own):
            raise FileExistsError(
                f"{str(folder)!r} already holds simulation files; pass "
                "overwrite=True (CLI: --overwrite) or choose a new folder"
            )
        # No link, no folder in the way of any file, checked before anything is written.
        targets = [output_path(folder, n, overwrite=True) for n in (*own, "truth_artefacts.csv")]
        self.campaign.save(folder, overwrite=overwrite)
        truth, truth_tests, readme, artefacts = targets
        write_atomic(truth, json.dumps(self.truth, indent=2, sort_keys=True) + "\n")
        # csv_text: text cells escaped against spreadsheet formulas, numbers as pandas writes.
        write_atomic(truth_tests, csv_text(self.test_truth))
        if len(self.artefacts):
            write_atomic(artefacts, csv_text(self.artefacts))
        write_atomic(readme, self._readme())
        return folder

    def _readme(self) -> str:
        spec = self.spec
        kinds = self.campaign.tests["kind"].value_counts()
        series = ", ".join(f"{s.name} ({s.kind})" for s in spec.series)
        return f"""# {spec.name} — SIMULATED campaign (not measured data)

{spec.description.strip() or "A campaign simulated by soilstats."}

**These data are simulated** by `soilstats.simulation.simulate` (soilstats
{self.truth["soilstats_version"]}) from SPEC `{spec.source}` (SHA-256 `{spec.sha256 or "-"}`)
with seed {self.seed}. No Bevameter produced them.

- {len(self.campaign.tests)} tests: {int(kinds.get("sinkage", 0))} sinkage,
  {int(kinds.get("shear", 0))} shear; series: {series}.
- `tests.csv`, `sinkage.csv`, `shear.csv`: the campaign format (docs/campaign-format.md);
  the `series` column names the test series of each test.
- `truth.json`: the soils' parameters, the planted effects, scatter, noise and resolution.
- `truth_tests.csv`: every test's drawn parameters (kc N/m^(n+1), kphi N/m^(n+2), n -,
  c Pa, phi deg, K m) and its soil-level values.{self._artefact_line()}

Regenerate (byte-identical) with

    soilstats simulate {spec.source} --out OUT --seed {self.seed}

run in the folder that holds `{spec.source}`; the format of the SPEC is in docs/simulator.md.
"""

    def _artefact_line(self) -> str:
        if not len(self.artefacts):
            return ""
        kinds = ", ".join(
            f"{k} ({n})" for k, n in self.artefacts["kind"].value_counts(sort=False).items()
        )
        return (
            "\n- `truth_artefacts.csv`: the record phases and glitches planted, one row each "
            f"(test, kind, its rows of sinkage.csv): {kinds}."
        )


def _as_spec(spec: Spec | dict | str | os.PathLike[str]) -> Spec:
    if isinstance(spec, Spec):
        return spec
    if isinstance(spec, dict):
        return parse_spec(spec)
    return load_spec(spec)


def _truth(spec: Spec, seed: int, biases: dict[tuple[str, str], float]) -> dict[str, Any]:
    def plain(v):
        if isinstance(v, dict):
            return {str(k): plain(x) for k, x in v.items()}
        if isinstance(v, list | tuple):
            return [plain(x) for x in v]
        return v

    return {
        "simulated": True,
        "seed": seed,
        "soilstats_version": __version__,
        "spec": {"name": spec.name, "source": spec.source, "sha256": spec.sha256},
        "units": {
            "kc": "N/m^(n+1)",
            "kphi": "N/m^(n+2)",
            "n": "-",
            "c": "Pa",
            "phi": "deg",
            "K": "m",
        },
        "soils": {
            name: {
                "params": soil.params,
                "conditions": [{"where": w, "params": p} for w, p in soil.conditions],
            }
            for name, soil in spec.soils.items()
        },
        "effects": [
            plain({"kind": e.kind, "soils": e.soils, "series": e.series, **e.options})
            for e in spec.effects
        ],
        "preparations": {
            name: {
                "scatter": dataclasses.asdict(p.scatter),
                "operator_cv": p.operator_cv,
                "operator_biases": {op: b for (pr, op), b in biases.items() if pr == name},
            }
            for name, p in spec.preparations.items()
        },
        "noise": dataclasses.asdict(spec.noise),
        "resolution": dataclasses.asdict(spec.resolution),
    } | (
        {
            "artefacts": [
                plain({"kind": a.kind, "soils": a.soils, "series": a.series, **a.options})
                for a in spec.artefacts
            ]
        }
        if spec.artefacts
        else {}
    )


def simulate(
    spec: Spec | dict | str | os.PathLike[str], *, seed: int, progress: bool = False
) -> SimulatedCampaign:
    """Simulate the campaign a SPEC describes.

    Parameters
    ----------
    spec : Spec, dict or path
        A checked :class:`Spec`, the dict of a parsed TOML file, or the path of a SPEC file
        (format in ``docs/simulator.md``).
    seed : int
        Seed of ``numpy.random.default_rng``; the only source of randomness.
    progress : bool
        Show a tqdm progress bar (on stderr) over the tests.

    Returns
    -------
    SimulatedCampaign

    Raises
    ------
    SpecError
        For a malformed SPEC (a ``ValueError`` naming the key and the valid options).
    """
    spec = _as_spec(spec)
    # A stream of its own for the artefacts: a SPEC without them simulates as it always did.
    param_rng, noise_rng, artefact_rng = np.random.default_rng(seed).spawn(3)
    biases = operator_biases(spec, param_rng)
    rows = expand(spec)
    _check_effect_columns(spec, rows)
    series_of = {s.name: s for s in spec.series}
    sink_parts: list[tuple[str, np.ndarray, np.ndarray]] = []
    shear_parts: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]] = []
    truth_rows = []
    planted: list[tuple[str, int, str, np.ndarray]] = []
    iterator = rows
    if progress:
        from tqdm import tqdm  # deferred: tqdm (a progress bar)

        iterator = tqdm(rows, desc=f"simulating {spec.name}", unit="test")
    for row in iterator:
        series = series_of[row["series"]]
        bias = biases[(row["preparation"], row["operator"])]
        params = draw_parameters(spec, row, param_rng, bias)
        _check_drawn(row, params)
        # The other law's parameters were drawn too (to keep the streams aligned) but do not
        # act on this test: report them as missing.
        unused = SHEAR_PARAMS if row["kind"] == "sinkage" else SINKAGE_PARAMS
        shown = {k: (np.nan if k.removesuffix("_soil") in unused else v) for k, v in params.items()}
        record = {
            "test_id": row["test_id"],
            "series": row["series"],
            "soil": row["soil"],
            "kind": row["kind"],
            **shown,
            "operator_bias": bias + 0.0,
        }
        if row["kind"] == "sinkage":
            soft = softening_of(spec.effects, row)
            z, force, offset = sinkage_samples(
                row,
                params,
                soft,
                spec.noise,
                spec.resolution,
                series.start_m,
                series.sinkage_m,
                series.points,
                noise_rng,
            )
            if spec.artefacts:
                z, force, found = _plant_artefacts(spec, row, z, force, artefact_rng)
                planted += [(row["test_id"], len(sink_parts), kind, at) for kind, at in found]
            sink_parts.append((row["test_id"], z, force))
            record["force_offset_N"] = offset
            record["softening_zc_m"], record["softening_factor"] = soft or (np.nan, np.nan)
        else:
            angle, torque, normal = _shear_test(spec, row, params, series, noise_rng, record)
            shear_parts.append((row["test_id"], angle, torque, normal))
        truth_rows.append(record)
    tests = pd.DataFrame([{k: v for k, v in r.items() if k not in _PRIVATE} for r in rows])
    order = [c for c in _LOG_ORDER if c in tests.columns]
    tests = tests[order + [c for c in tests.columns if c not in order]]
    sinkage = _stack(sink_parts, ("z_m", "force_N"))
    shear = _stack(shear_parts, ("angle_rad", "torque_Nm", "normal_force_N"))
    campaign = Campaign.from_frames(
        tests, sinkage, shear, source=f"simulated:{spec.name}:seed={seed}"
    )
    test_truth = pd.DataFrame(truth_rows)
    artefacts = _artefact_table(planted, sink_parts)
    truth = _truth(spec, seed, biases)
    return SimulatedCampaign(campaign, truth, test_truth, spec, seed, artefacts)


def _shear_test(
    spec: Spec,
    row: dict[str, Any],
    params: dict[str, float],
    series: Series,
    rng: np.random.Generator,
    record: dict[str, Any],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One shear test's samples (angle [rad], torque [N m], normal force [N]), its truth
    (offset, side-wall K0 and the apparent c and φ the ring measures) added to ``record``."""
    K0 = side_wall_K0(spec.effects, row)
    angle, torque, normal, offset = shear_samples(
        row,
        params,
        K0,
        spec.noise,
        spec.resolution,
        series.shear_deformation_m,
        series.points,
        rng,
    )
    record["torque_offset_Nm"] = offset
    a = side_wall_ratio(row["r_inner_m"], row["r_outer_m"], row["grouser_height_m"])
    k0, a = (0.0, 0.0) if K0 is None else (K0, a)
    record["normal_pressure_Pa"] = row["normal_pressure_Pa"]
    record["side_wall_K0"] = np.nan if K0 is None else K0
    record["c_apparent_Pa"], record["phi_apparent_deg"] = apparent_shear(
        params["c"], params["phi"], a, k0
    )
    record["c_apparent_soil"], record["phi_apparent_soil"] = apparent_shear(
        params["c_soil"], params["phi_soil"], a, k0
    )
    return angle, torque, normal


def _check_effect_columns(spec: Spec, rows: list[dict[str, Any]]) -> None:
    """A covariate effect on a column no test it applies to has: refused (it would plant
    nothing, silently)."""
    for i, effect in enumerate(spec.effects):
        if effect.kind != "covariate":
            continue
        column = effect.options["column"]
        applies = [r for r in rows if effect.applies(r["soil"], r["series"])]
        if not any(column in r for r in applies):
            have = sorted({k for r in applies for k in r if k not in _PRIVATE})
            raise SpecError(
                f"SPEC [[effects]][{i}].column: {column!r} is not a test-log column of the "
                f"tests this effect applies to (columns: {have}); add it as a covariate, a "
                "preparation key or a plate/ring key"
            )


def _check_drawn(row: dict[str, Any], params: dict[str, float]) -> None:
    """A test's parameters after effects and scatter must lie in the models' support."""
    bad = outside_support(params, row["kind"], row.get("b_m") if row["kind"] == "sinkage" else None)
    if bad:
        raise SpecError(
            f"SPEC: test {row['test_id']} (soil {row['soil']}, series {row['series']}) draws "
            f"{'; '.join(bad)} — the soil's values with the effects and scatter leave the "
            "models' support; move the soil's value or reduce the effect or the scatter"
        )


def _plant_artefacts(
    spec: Spec, row: dict, z: np.ndarray, force: np.ndarray, rng: np.random.Generator
) -> tuple:
    """``spec``'s artefacts planted in one sinkage record, in SPEC order: (z, force,
    [(kind, positions)]). One uniform number is drawn per matching artefact whether or not
    it is planted, so ``share`` leaves the other tests' draws alone."""
    found: list[tuple[str, np.ndarray]] = []
    for artefact in spec.artefacts:
        if not artefact.applies(row["soil"], row["series"]):
            continue
        if rng.random() >= artefact.options["share"]:
            continue
        z, force, mask, inserted = plant(
            artefact.kind, artefact.options, z, force, rng, spec.noise.force_N
        )
        found = [(kind, _stretch(at, inserted)) for kind, at in found]
        found.append((artefact.kind, np.flatnonzero(mask)))
    z = quantise(z, spec.resolution.z_m)
    force = quantise(force, spec.resolution.force_N)
    return z, force, found


def _stretch(positions: np.ndarray, inserted: np.ndarray) -> np.ndarray:
    """Positions in a record after samples were inserted (``inserted``: the new record's
    mask of the added samples)."""
    return np.flatnonzero(~inserted)[positions] if inserted.any() else positions


def _artefact_table(planted: list, sink_parts: list) -> pd.DataFrame:
    """The planted artefacts with their 1-based rows of sinkage.csv."""
    starts = np.cumsum([0] + [p[1].size for p in sink_parts])
    records = []
    for test_id, part, kind, at in planted:
        rows = starts[part] + at + 1
        first, last = (int(rows.min()), int(rows.max())) if rows.size else (0, 0)
        text = " ".join(str(int(r)) for r in rows)
        records.append((test_id, kind, first, last, int(rows.size), text))
    return pd.DataFrame(records, columns=list(_ARTEFACT_COLUMNS))


def _stack(parts: list[tuple], columns: tuple[str, ...]) -> pd.DataFrame | None:
    if not parts:
        return None
    ids = np.concatenate([np.full(p[1].size, p[0], dtype=object) for p in parts])
    data = {"test_id": ids}
    for i, col in enumerate(columns, start=1):
        data[col] = np.concatenate([p[i] for p in parts])
    return pd.DataFrame(data)
