"""Parameter sets for wheel–soil simulators, from posterior draws.

``chrono-scm``: Project Chrono's SCM deformable terrain,
``SCMTerrain::SetSoilParameters(Bekker_Kphi, Bekker_Kc, Bekker_n, Mohr_cohesion,
Mohr_friction, Janosi_shear, elastic_K, damping_R)``, one row per joint draw in that order.
SCM's pressure is σ = (Kc/b + Kφ)·z^n, τ = (c + σ tan φ)(1 − e^(−j/K)): in SI units Kφ
[Pa/m^n] is Bekker's kφ [N/m^(n+2)] and Kc [Pa/m^(n−1)] Bekker's kc [N/m^(n+1)], so the
draws are copied, not converted (``Model.scm`` of each model's record names the column).

Where each column comes from (:attr:`SimulatorExport.sources`, written into the files):

* **the draws** — Bekker kφ, kc, n; c, φ (Janosi or Mohr–Coulomb), K (Janosi);
* **the Bernstein mapping** — Bernstein's p = k·z^n is Bekker's law without its plate-size
  term: Bekker_Kphi = k, Bekker_Kc = 0. SCM's pressure then ignores the contact patch's size,
  which is right only near the plate size(s) k was measured on (say so, the record does);
* **user priors** (:mod:`soilstats.bayes.stated_priors`, the one implementation of stated priors)
  for what no test measured — c, φ, K of a campaign without shear-ring tests. They are drawn
  from their own seeded generator, independently of the posterior draws: no correlation
  between them and the measured parameters is invented;
* **stated inputs** — elastic_K [Pa/m] and damping_R [Pa s/m] are not Bevameter parameters
  (SCM's elastic unloading stiffness and damping): by default the values of Chrono's own SCM
  demos (4e7 Pa/m, 3e4 Pa s/m), or the user's.

SCM's own constraints (:data:`SCM_CONSTRAINTS`, read from Chrono's source) are checked on
every row (:mod:`soilstats.bayes.scm_constraints`, the check and the repair). Chrono does
not refuse a set that breaks them: ``SetSoilParameters`` silently raises elastic_K to
Bekker_Kphi, and the rest it computes with. Here a row that breaks one is never handed out
silently: the check fails (the caller refuses), or, with ``repair=M``, a row whose
elastic_K ≤ Bekker_Kphi gets elastic_K = M·Bekker_Kphi and is marked in the column
``elastic_K_repaired``.

Chrono references are to ``src/chrono_vehicle/terrain/SCMTerrain.cpp`` / ``SCMTerrain.h`` of
projectchrono/chrono at commit 7689fbc02d12 (August 2026).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import cast

import numpy as np
import pandas as pd

from ..errors import InputError
from ..models import MODELS
from .scm_constraints import (
    CHRONO_SOURCE,
    REPAIR_MAX,
    REPAIRABLE,
    REPAIRED,
    SCM_ARGUMENTS,
    SCM_CONSTRAINTS,
    ConstraintCheck,
    SimulatorConstraintError,
    check_scm,
    constraint_failures,
)
from .stated_priors import describe_prior, sample_priors, stated_priors_of
from .support import SupportCheck, negative_modulus_width

# The check and repair live in .scm_constraints; their names stay importable from here.
__all__ = [
    "CHRONO_SOURCE",
    "REPAIRABLE",
    "REPAIRED",
    "REPAIR_MAX",
    "SCM_CONSTRAINTS",
    "SCM_DEFAULTS",
    "SIMULATOR_FORMATS",
    "ConstraintCheck",
    "SimulatorConstraintError",
    "SimulatorExport",
    "check_scm",
    "constraint_failures",
    "export_simulator",
    "missing_message",
    "scm_plan",
    "stated_inputs",
]


def _scm_format() -> dict[str, tuple[str, str]]:
    """SCM's column and unit of each parameter, from the paper's model records
    (``Model.scm``: Bekker's Kphi, Kc, n; Janosi's and Mohr–Coulomb's cohesion, friction,
    Janosi shear), in the order of registration; the first record to map a parameter names
    its column."""
    out: dict[str, tuple[str, str]] = {}
    for model in MODELS.values():
        for name, column in cast(tuple, model.scm):  # pairs once built
            out.setdefault(name, column)
    return out


#: Column names and units of the parameter sets simulators consume. ``chrono-scm``:
#: Kphi [Pa/m^n] = N/m^(n+2), Kc [Pa/m^(n−1)] = N/m^(n+1), cohesion [Pa], friction [deg],
#: Janosi shear [m] — the mapping each model's record states (``Model.scm``).
SIMULATOR_FORMATS = {"chrono-scm": _scm_format()}

#: SCM's stated (non-Bevameter) inputs: value, unit, and where the default comes from.
SCM_DEFAULTS = {
    "elastic_K": (4e7, "Pa/m", "Chrono SCM demos (SetSoilParameters(..., 4e7, 3e4))"),
    "damping_R": (3e4, "Pa s/m", "Chrono SCM demos (SetSoilParameters(..., 4e7, 3e4))"),
}

#: Bernstein's p = k z^n as Bekker's law: Kphi = k, Kc = 0 (no plate-size term).
_BERNSTEIN = {"kphi": "k", "kc": 0.0}
#: The sinkage parameters SCM takes (Bekker's); the rest are shear parameters.
_SINKAGE = ("kphi", "kc", "n")


def scm_plan(available: Iterable[str], priors: Iterable[str] = ()) -> dict[str, str]:
    """Where each SCM parameter will come from: ``"draws"``, ``"bernstein"`` (the Bernstein
    mapping), ``"prior"`` (a user prior) or ``"missing"``.

    ``available``: the parameter names of the draws (or of the models to be sampled);
    ``priors``: the names given user priors. A prior is taken only for a parameter the draws
    lack; a sinkage parameter the Bernstein mapping gives takes none.
    """
    have, stated = set(available), set(priors)
    bernstein = "kphi" not in have and {"k", "n"} <= have
    out = {}
    for key in SIMULATOR_FORMATS["chrono-scm"]:
        if key in have:
            out[key] = "draws"
        elif bernstein and key in _BERNSTEIN:
            out[key] = "bernstein"
        elif key in stated:
            out[key] = "prior"
        else:
            out[key] = "missing"
    return out


@dataclass(frozen=True)
class SimulatorExport:
    """A simulator's parameter sets, where each column came from, and SCM's check.

    Attributes
    ----------
    simulator : str
    table : DataFrame
        One row per draw: the simulator's columns in its argument order, then
        ``elastic_K_repaired`` (1 where a repair set elastic_K).
    sources : dict
        Column -> where its values came from (draws, mapping, user prior, stated input).
    stated : dict
        elastic_K, damping_R -> (value, unit, source).
    check : ConstraintCheck
    notes : tuple of str
        What the user of the sets must know (negative modulus, Bernstein mapping, priors).
    negative_modulus_below_m : float or None
        Where kc < 0: the contact width below which Kc/b + Kphi turns negative (99 % of rows).
    """

    simulator: str
    table: pd.DataFrame
    sources: dict[str, str]
    stated: dict
    check: ConstraintCheck
    notes: tuple[str, ...]
    negative_modulus_below_m: float | None = None

    def from_priors(self) -> list[str]:
        """The columns drawn from user priors."""
        return [k for k, v in self.sources.items() if v.startswith("user prior")]

    def record(self, support: SupportCheck | None = None, context: Mapping | None = None) -> dict:
        """The JSON record beside the CSV (module docstring)."""
        spec = SIMULATOR_FORMATS[self.simulator]
        out = {
            "simulator": self.simulator,
            "call": "SCMTerrain::SetSoilParameters(" + ", ".join(SCM_ARGUMENTS) + ")",
            "arguments": list(SCM_ARGUMENTS),
            "columns": {name: unit for name, unit in spec.values()}
            | {name: unit for name, (_, unit, _) in self.stated.items()}
            | {REPAIRED: "1 where elastic_K was repaired, else 0"},
            "sources": dict(self.sources),
            "stated_inputs": {
                name: {"value": value, "unit": unit, "source": source}
                for name, (value, unit, source) in self.stated.items()
            },
            "draws": len(self.table),
            "constraints": self.check.to_dict(),
            **dict(context or {}),
        }
        if support is not None:
            out["support"] = support.to_dict()
        if self.negative_modulus_below_m is not None:
            out["negative_modulus_below_m"] = self.negative_modulus_below_m
        out["notes"] = list(self.notes)
        return out

    def comment_lines(self) -> list[str]:
        """``key: value`` lines for the CSV's comment header: the call, each column's
        source, SCM's check and the repair."""
        lines = [
            f"simulator: {self.simulator}, columns 1-8 are the arguments of "
            f"SCMTerrain::SetSoilParameters in order"
        ]
        lines += [f"source {name}: {source}" for name, source in self.sources.items()]
        lines.append(f"scm constraints: {self.check.describe()}")
        lines += [f"note: {note}" for note in self.notes]
        return lines


def stated_inputs(elastic_K: float | None = None, damping_R: float | None = None) -> dict:
    """SCM's stated inputs: name -> (value, unit, source), the defaults where None.

    Raises ValueError unless elastic_K > 0 (SCM divides by it) and damping_R >= 0 (0 is
    Chrono's own default, the original SCM).
    """
    given = {"elastic_K": elastic_K, "damping_R": damping_R}
    out = {}
    for name, value in given.items():
        default, unit, source = SCM_DEFAULTS[name]
        if value is not None:
            # elastic_K divides (SCMTerrain.cpp:1764); a negative damping adds energy (:1773).
            ok = value > 0 if name == "elastic_K" else value >= 0
            if not (ok and np.isfinite(value)):
                need = "positive" if name == "elastic_K" else "zero or positive"
                raise InputError(f"{name} must be {need} and finite, got {value!r}")
        out[name] = (default, unit, source) if value is None else (value, unit, "stated by user")
    return out


def _source_of(key: str, plan: str, draws_source: Mapping, priors: Mapping) -> str:
    if plan == "draws":
        return draws_source.get(key, "posterior draws")
    if plan == "bernstein" and key == "kc":
        return "0 by the Bernstein mapping (p = k z^n is Bekker's law with Kc = 0)"
    if plan == "bernstein":
        taken = draws_source.get("k", "posterior draws")
        return f"{taken} of Bernstein's k (Bernstein mapping: Kphi = k)"
    unit = SIMULATOR_FORMATS["chrono-scm"][key][1]
    return (
        f"user prior {describe_prior(priors[key])} {unit}, drawn independently of the "
        "posterior draws (not measured)"
    )


def _column(key: str, plan: str, draws: pd.DataFrame, drawn: Mapping) -> np.ndarray:
    if plan == "draws":
        return draws[key].to_numpy(float)
    if plan == "prior":
        return np.asarray(drawn[key], float)
    value = _BERNSTEIN[key]
    return draws[value].to_numpy(float) if isinstance(value, str) else np.full(len(draws), value)


def _widths(plate_widths: tuple[float, float] | None) -> str:
    if plate_widths is None:
        return "the data's size"
    lo, hi = plate_widths
    return f"b = {lo:g} m" if lo == hi else f"b = {lo:g}-{hi:g} m"


def _notes(
    table: pd.DataFrame,
    draws: pd.DataFrame,
    plan: dict[str, str],
    priors: Mapping[str, tuple],
    width: float | None,
    seed: int | None,
    plate_widths: tuple[float, float] | None,
) -> tuple[str, ...]:
    notes = []
    if width is not None:
        share = float((draws["kc"] < 0).mean())
        notes.append(
            f"kc < 0 in {share:.0%} of the draws: SCM's pressure (Kc/b + Kphi) z^n turns "
            f"negative on contact patches with b below {width:.3g} m (99 % of draws), where "
            "SCM takes 1/b = perimeter / (2 area) of the patch (SCMTerrain.cpp:1671; a circle's "
            "radius, l w / (l + w) for an l x w rectangle) and does not guard the sign "
            "(SCMTerrain.cpp:1761): do not use these sets for narrower contacts"
        )
    if "bernstein" in plan.values():
        notes.append(
            "Bernstein mapping: Bekker_Kphi = k, Bekker_Kc = 0, so SCM's pressure does not "
            f"depend on the contact patch's size; k was measured on plates of "
            f"{_widths(plate_widths)} and holds for contacts of about that size only"
        )
    spec = SIMULATOR_FORMATS["chrono-scm"]
    taken = [
        f"{spec[k][0]} ~ {describe_prior(priors[k])} {spec[k][1]}"
        for k, v in plan.items()
        if v == "prior"
    ]
    if taken:
        notes.append(
            f"user priors, not tests: {', '.join(taken)}; drawn (seed {seed}) independently "
            "of the posterior draws, so no correlation with the measured parameters is carried"
        )
    n = table["Bekker_n"].to_numpy(float)
    unusual = int(((n < 0.6) | (n > 1.8)).sum())
    if unusual:
        notes.append(
            f"Bekker_n outside 0.6-1.8 ('usually', SCMTerrain.h:137) in {unusual} of {len(n)} "
            "sets: not a constraint of SCM, but outside the range its authors had in mind"
        )
    return tuple(notes)


def export_simulator(
    draws: pd.DataFrame,
    simulator: str = "chrono-scm",
    *,
    elastic_K: float | None = None,
    damping_R: float | None = None,
    priors: Mapping[str, tuple | str] | Iterable[str] | None = None,
    seed: int | None = None,
    repair: float | None = None,
    draws_source: str | Mapping[str, str] = "posterior draws",
    plate_widths: tuple[float, float] | None = None,
    on_failure: str = "raise",
) -> SimulatorExport:
    """The draws as a simulator's parameter sets, with their sources and SCM's check.

    Parameters
    ----------
    draws : DataFrame
        Joint draws (columns named as the models' parameters, SI, φ in degrees): Bekker's
        (kc, kphi, n) or Bernstein's (k, n), and c, phi, K where a shear test measured them.
    elastic_K, damping_R : float, optional
        SCM's elastic stiffness [Pa/m] (> 0) and damping [Pa s/m] (>= 0); default
        :data:`SCM_DEFAULTS`.
    priors : mapping or sequence of str, optional
        User priors for the parameters the draws lack, as :mod:`soilstats.bayes.stated_priors`
        tuples (``{"c": ("uniform", 0, 2000), "phi": ("normal", 30, 3), "K": ("lognormal",
        0.02, 0.5)}``; c Pa, φ deg, K m), as the CLI's text forms (``{"c": "uniform:0:2000"}``)
        or as the CLI's ``--prior`` strings (``["c=uniform:0:2000", "phi=normal:30:3"]``).
        A prior for a parameter the draws hold is an error.
    seed : int, optional
        Seed of the prior draws (required with ``priors``); give one independent of the
        posterior's.
    repair : float, optional
        A multiple M > 1: rows with elastic_K ≤ Bekker_Kphi get elastic_K = M·Bekker_Kphi,
        marked in ``elastic_K_repaired``. Without it such rows fail the check.
    draws_source : str or mapping
        How the draws' columns are described in ``sources`` (per parameter if a mapping).
    plate_widths : (b_min, b_max), optional
        The plate sizes [m] the sinkage draws were measured on (named in the Bernstein note).
    on_failure : {"raise", "return"}
        Rows that break SCM's constraints (sets Chrono would silently change) raise
        :class:`SimulatorConstraintError` naming each failure and its fix, as
        ``soilstats posterior --simulator`` refuses them (the default); ``"return"`` returns
        the export with its failed ``check`` for the caller to inspect.

    Raises
    ------
    SimulatorConstraintError
        With ``on_failure="raise"``: a row breaks SCM's constraints (see ``repair``).
    ValueError
        A parameter SCM needs is neither in the draws nor given a prior; a prior for a
        parameter the draws hold; bad stated inputs or prior draws outside the support.
    """
    if on_failure not in ("raise", "return"):
        raise InputError(f"on_failure must be 'raise' or 'return', got {on_failure!r}")
    try:
        spec = SIMULATOR_FORMATS[simulator]
    except KeyError:
        raise InputError(
            f"unknown simulator {simulator!r}; choose one of {sorted(SIMULATOR_FORMATS)}"
        ) from None
    priors = stated_priors_of(priors)
    plan = scm_plan(draws.columns, priors)
    missing = [k for k, v in plan.items() if v == "missing"]
    if missing:
        raise InputError(missing_message(simulator, missing, draws.columns))
    unused = sorted(set(priors) - {k for k, v in plan.items() if v == "prior"})
    if unused:
        raise InputError(
            f"priors given for {unused}, which the draws already carry or {simulator} does not "
            "take; user priors are for the parameters no test measured"
        )
    if priors and seed is None:
        raise InputError("user priors need a seed (give one independent of the posterior's)")
    stated = stated_inputs(elastic_K, damping_R)
    drawn = sample_priors(priors, len(draws), int(cast(int, seed))) if priors else {}
    if not isinstance(draws_source, Mapping):
        draws_source = dict.fromkeys(draws.columns, str(draws_source))
    columns = {name: _column(key, plan[key], draws, drawn) for key, (name, _) in spec.items()}
    sources = {
        name: _source_of(key, plan[key], draws_source, priors) for key, (name, _) in spec.items()
    }
    for name, (value, _, source) in stated.items():
        columns[name] = np.full(len(draws), float(value))
        sources[name] = f"stated input {value:g} ({source})"
    table, check = check_scm(pd.DataFrame(columns), repair)
    if check.repaired.any():
        sources["elastic_K"] += (
            f"; {repair:g} x Bekker_Kphi in the {int(check.repaired.sum())} rows repaired"
        )
    width = negative_modulus_width(draws) if plan["kc"] == "draws" else None
    notes = _notes(table, draws, plan, priors, width, seed, plate_widths)
    if on_failure == "raise" and not check.passed:
        raise SimulatorConstraintError("; ".join(constraint_failures(simulator, check)), check)
    return SimulatorExport(simulator, table, sources, stated, check, notes, width)


def missing_message(simulator: str, missing: Iterable[str], available: Iterable[str]) -> str:
    """Says what a simulator lacks and how to give it (one line)."""
    spec = SIMULATOR_FORMATS[simulator]
    missing = list(missing)
    named = ", ".join(f"{spec[k][0]} ({k} [{spec[k][1]}])" for k in missing)
    shear = [k for k in missing if k not in _SINKAGE]
    example = {"c": "c=uniform:0:2000", "phi": "phi=normal:30:3", "K": "K=lognormal:0.02:0.5"}
    hint = " ".join(f"--prior {example.get(k, k + '=...')}" for k in missing)
    fix = (
        f"add a shear model (e.g. --model bekker+janosi) or state user priors: {hint}"
        if shear
        else f"add a Bekker or Bernstein sinkage model, or state user priors: {hint}"
    )
    return (
        f"{simulator} needs {named}, which the draws ({', '.join(available) or 'none'}) lack "
        f"and no prior gives: {fix}"
    )
