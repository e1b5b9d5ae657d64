"""SCM's own constraints on a parameter set, checked row by row, and the one repair
allowed (elastic_K, a stated input): the check-and-repair half of the simulator export
(:mod:`soilstats.bayes.export` maps the draws and records them; split out of it, issue #45).

The conditions (:data:`SCM_CONSTRAINTS`) are read from Chrono's source
(:data:`CHRONO_SOURCE`). Chrono does not refuse a set that breaks them:
``SetSoilParameters`` silently raises elastic_K to Bekker_Kphi, and the rest it computes
with. Here a row that breaks one is never handed out silently: :func:`check_scm` says which
rows break which condition (:class:`ConstraintCheck`), or, with ``repair=M``, gives a row
whose elastic_K ≤ Bekker_Kphi elastic_K = M·Bekker_Kphi and marks it in the column
:data:`REPAIRED`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import cast

import numpy as np
import pandas as pd

from ..errors import InputError, SoilstatsError, warn_renamed

__all__ = [
    "CHRONO_SOURCE",
    "REPAIRABLE",
    "REPAIRED",
    "REPAIR_MAX",
    "SCM_ARGUMENTS",
    "SCM_CONSTRAINTS",
    "ConstraintCheck",
    "SimulatorConstraintError",
    "check_scm",
    "constraint_failures",
]

#: Where the constraints below were read.
CHRONO_SOURCE = (
    "projectchrono/chrono 7689fbc02d12, src/chrono_vehicle/terrain/SCMTerrain.cpp and SCMTerrain.h"
)

#: Marks of the column that records a repair of elastic_K, row by row.
REPAIRED = "elastic_K_repaired"


@dataclass(frozen=True)
class Constraint:
    """One of SCM's conditions on a parameter set (a row).

    ``holds(table)`` gives, per row, whether it holds; ``chrono`` says where Chrono states or
    uses it; ``otherwise`` what Chrono does with a row that breaks it.
    """

    label: str
    holds: Callable[[pd.DataFrame], np.ndarray] = field(repr=False)
    chrono: str
    otherwise: str


def _finite(table: pd.DataFrame) -> np.ndarray:
    return np.isfinite(table[list(SCM_ARGUMENTS)].to_numpy(float)).all(axis=1)


#: The arguments of ``SCMTerrain::SetSoilParameters``, in their order (the table's columns).
SCM_ARGUMENTS = (
    "Bekker_Kphi",
    "Bekker_Kc",
    "Bekker_n",
    "Mohr_cohesion",
    "Mohr_friction",
    "Janosi_shear",
    "elastic_K",
    "damping_R",
)

#: SCM's conditions on each row, read from Chrono's source (:data:`CHRONO_SOURCE`). Chrono
#: checks none of them: it clamps the first silently and computes with the others.
SCM_CONSTRAINTS: tuple[Constraint, ...] = (
    Constraint(
        "elastic_K > Bekker_Kphi",
        lambda t: t["elastic_K"].to_numpy(float) > t["Bekker_Kphi"].to_numpy(float),
        "SCMTerrain.h:141 (elastic_K 'must be larger than Kphi'); SCMTerrain.cpp:193 "
        "m_elastic_K = std::max(elastic_K, Bekker_Kphi)",
        "Chrono would silently raise their elastic_K to Bekker_Kphi (through a "
        "SoilParametersCallback, SCMTerrain.cpp:1721, not even that)",
    ),
    Constraint(
        "finite",
        _finite,
        "SCMTerrain.cpp:1729-1780 (every value enters the node forces)",
        "Chrono would compute non-finite forces",
    ),
    Constraint(
        "Bekker_Kphi > 0",
        lambda t: t["Bekker_Kphi"].to_numpy(float) > 0,
        "SCMTerrain.cpp:1668-1671 (1/b = 0 on contact patches under 1e-6 m^2, so the pressure "
        "there is Kphi z^n)",
        "Chrono would give zero or negative pressure on small patches",
    ),
    Constraint(
        "Bekker_n > 0",
        lambda t: t["Bekker_n"].to_numpy(float) > 0,
        "SCMTerrain.cpp:1761 ((Kc/b + Kphi) * pow(z, n))",
        "Chrono's pressure would not grow with sinkage",
    ),
    Constraint(
        "Mohr_cohesion >= 0",
        lambda t: t["Mohr_cohesion"].to_numpy(float) >= 0,
        "SCMTerrain.cpp:1777 (tau_max = c + sigma tan(phi))",
        "Chrono would give a negative shear strength at low pressure",
    ),
    Constraint(
        "0 <= Mohr_friction < 90",
        lambda t: (t["Mohr_friction"] >= 0).to_numpy() & (t["Mohr_friction"] < 90).to_numpy(),
        "SCMTerrain.cpp:191 (tan(Mohr_friction in degrees))",
        "Chrono would use an infinite or negative friction coefficient",
    ),
    Constraint(
        "Janosi_shear > 0",
        lambda t: t["Janosi_shear"].to_numpy(float) > 0,
        "SCMTerrain.cpp:1780 (1 - exp(-j / Janosi_shear))",
        "Chrono would divide by zero, or let the shear stress grow without bound",
    ),
)

#: Largest elastic_K repair multiple: beyond 1000 x Bekker_Kphi it is no repair but a typo.
REPAIR_MAX = 1000.0
#: The constraint a repair may fix (elastic_K is a stated input, not a measured parameter).
REPAIRABLE = "elastic_K > Bekker_Kphi"


class SimulatorConstraintError(SoilstatsError, ValueError):
    """Parameter sets break a simulator's constraints; ``check`` says which rows and why."""

    def __init__(self, message: str, check: ConstraintCheck) -> None:
        super().__init__(message)
        self.check = check


@dataclass(frozen=True)
class ConstraintCheck:
    """Which rows of a parameter table break SCM's constraints, and which were repaired.

    Attributes
    ----------
    broken : dict
        Constraint label -> bool per row: broken *before* any repair.
    repaired : ndarray of bool
        Rows whose elastic_K was set to ``repair_multiple`` × Bekker_Kphi.
    repair_multiple : float or None
        The stated multiple (None: no repair asked for).
    largest_kphi : float
        The largest Bekker_Kphi of the rows [Pa/m^n] (an elastic_K above it passes).
    """

    broken: dict[str, np.ndarray]
    repaired: np.ndarray
    repair_multiple: float | None
    largest_kphi: float

    @property
    def rows(self) -> int:
        return len(self.repaired)

    def still_broken(self, label: str) -> np.ndarray:
        """Rows that break the constraint ``label`` after the repair."""
        rows = self.broken[label]
        return rows & ~self.repaired if label == REPAIRABLE else rows

    @property
    def failing(self) -> np.ndarray:
        """Rows that still break a constraint after the repair."""
        out = np.zeros(self.rows, bool)
        for label in self.broken:
            out |= self.still_broken(label)
        return out

    @property
    def passed(self) -> bool:
        return not self.failing.any()

    def counts(self) -> dict[str, int]:
        return {label: int(rows.sum()) for label, rows in self.broken.items()}

    @property
    def failures(self) -> tuple[str, ...]:
        """One sentence per constraint still broken (empty when the check passed), as
        :attr:`Handout.failures <soilstats.bayes.handout.Handout.failures>` names the reasons
        a check did not pass."""
        out = []
        for c in SCM_CONSTRAINTS:
            rows = self.still_broken(c.label)
            if rows.any():
                out.append(
                    f"{int(rows.sum())} of {self.rows} parameter sets break SCM's {c.label} "
                    f"({c.chrono}): {c.otherwise}"
                )
        return tuple(out)

    def problems(self) -> list[str]:
        """Renamed :attr:`failures` (docs/conventions.md, "Renamed"), as a list."""
        warn_renamed("ConstraintCheck.problems()", "ConstraintCheck.failures")
        return list(self.failures)

    def repair_sentence(self) -> str:
        """What the repair did, or '' when nothing was repaired."""
        n = int(self.repaired.sum())
        if not n:
            return ""
        return (
            f"elastic_K repaired in {n} of {self.rows} parameter sets: they broke SCM's "
            f"{REPAIRABLE}, so elastic_K = {self.repair_multiple:g} x Bekker_Kphi there "
            f"(column {REPAIRED} = 1), instead of the stated value"
        )

    def describe(self) -> str:
        """One line: passed, repaired or broken, with counts."""
        said = [s for s in (*self.failures, self.repair_sentence()) if s]
        return "; ".join(said) or f"all {self.rows} parameter sets meet SCM's constraints"

    def to_dict(self) -> dict:
        return {
            "rows": self.rows,
            "passed": self.passed,
            "broken": self.counts(),
            "repaired": int(self.repaired.sum()),
            "repair_multiple": self.repair_multiple,
            "largest_Bekker_Kphi": self.largest_kphi,
            "constraints": {
                c.label: {"chrono": c.chrono, "otherwise": c.otherwise} for c in SCM_CONSTRAINTS
            },
            "chrono_source": CHRONO_SOURCE,
        }


def check_scm(
    table: pd.DataFrame, repair: float | None = None
) -> tuple[pd.DataFrame, ConstraintCheck]:
    """Check every row of an SCM table against :data:`SCM_CONSTRAINTS`; with ``repair`` (a
    multiple > 1), set elastic_K = repair × Bekker_Kphi in the rows where elastic_K ≤
    Bekker_Kphi, and mark them. Returns the (repaired) table and the check."""
    if repair is not None and not (np.isfinite(repair) and 1 < repair <= REPAIR_MAX):
        raise InputError(
            f"the elastic_K repair multiple must be a number in (1, {REPAIR_MAX:g}] (elastic_K "
            f"= multiple x Bekker_Kphi must exceed Bekker_Kphi), got {repair!r}"
        )
    with np.errstate(invalid="ignore"):
        broken = {c.label: ~np.asarray(c.holds(table), bool) for c in SCM_CONSTRAINTS}
    kphi = table["Bekker_Kphi"].to_numpy(float)
    repaired = broken[REPAIRABLE] & (kphi > 0) if repair is not None else np.zeros(len(table), bool)
    table = table.copy()
    if repaired.any():
        with np.errstate(over="ignore"):
            new_K = cast(float, repair) * kphi[repaired]
        if not np.all(np.isfinite(new_K)):  # a Bekker_Kphi near the float maximum
            raise InputError(
                f"repairing elastic_K = {repair:g} x Bekker_Kphi overflows in "
                f"{int((~np.isfinite(new_K)).sum())} rows; state --scm-elastic-K instead"
            )
        table.loc[repaired, "elastic_K"] = new_K
    table[REPAIRED] = repaired.astype(int)
    largest = float(np.nanmax(kphi)) if len(kphi) else float("nan")
    return table, ConstraintCheck(broken, repaired, repair, largest)


def constraint_failures(
    simulator: str, check: ConstraintCheck, *, arguments: bool = True
) -> list[str]:
    """The failed constraints, each with its fix (a larger elastic_K or a repair multiple):
    the words of :class:`SimulatorConstraintError` and (``arguments=False``: the options
    only, not :func:`export_simulator`'s argument names) of the CLI's refusal."""
    elastic, repair = (" (elastic_K=)", " (repair=)") if arguments else ("", "")
    fix = (
        f". Fix: state --scm-elastic-K{elastic} above {check.largest_kphi:.3g} Pa/m (the "
        "largest Bekker_Kphi; best a measured unloading stiffness), or pass --scm-repair "
        f"MULTIPLE{repair} to set elastic_K = MULTIPLE x Bekker_Kphi in each such set (marked "
        "per row)"
    )
    return [
        f"{simulator}: {failure}{fix if REPAIRABLE in failure else ''}"
        for failure in check.failures
    ]
