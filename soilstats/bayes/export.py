"""Parameter sets for wheel–soil simulators, from posterior draws.

``chrono-scm``: Project Chrono's SCM deformable terrain,
``SCMTerrain::SetSoilParameters(Bekker_Kphi, Bekker_Kc, Bekker_n, Mohr_cohesion,
Mohr_friction, Janosi_shear, elastic_K, damping_R)``. Bevameter tests give the first six.
The last two are *not* Bevameter parameters — SCM's elastic unloading stiffness per unit area
[Pa/m] and its damping [Pa s/m] — so they are stated inputs: by default the values of
Chrono's own SCM demos (elastic_K = 4e7 Pa/m, damping_R = 3e4 Pa s/m), replaced by
``--scm-elastic-K`` / ``--scm-damping-R`` where a lab has measured unloading curves. SCM
requires elastic_K > Bekker_Kphi; a draw that breaks it is counted in the record.

Each export is a CSV (one row per joint draw) and a JSON record: the simulator, units, the
stated inputs and where they came from, seed, soil, selection, soilstats version, the
physical-support check, and — where kc < 0 — the contact width below which Bekker's modulus
kc/b + kφ turns negative (a simulator must not use the draws below it).
"""

from __future__ import annotations

import pandas as pd

from .support import negative_modulus_width

__all__ = ["SCM_DEFAULTS", "SIMULATOR_FORMATS", "simulator_parameters", "simulator_record"]


def _scm_format() -> dict[str, tuple[str, str]]:
    """SCM's column and unit of each parameter, from the paper's model records
    (``Model.scm``: Bekker's Kphi, Kc, n; Janosi's and Mohr–Coulomb's cohesion, friction,
    Janosi shear), in the order of registration; the first record to map a parameter names
    its column."""
    from ..models import MODELS

    out: dict[str, tuple[str, str]] = {}
    for model in MODELS.values():
        for name, column in model.scm:
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


def simulator_parameters(
    draws: pd.DataFrame,
    simulator: str = "chrono-scm",
    *,
    elastic_K: float | None = None,
    damping_R: float | None = None,
) -> pd.DataFrame:
    """Joint draws renamed to a simulator's parameters, with its stated inputs as columns.

    ``elastic_K`` [Pa/m] and ``damping_R`` [Pa s/m]: SCM's elastic stiffness and damping
    (default :data:`SCM_DEFAULTS`).
    """
    try:
        spec = SIMULATOR_FORMATS[simulator]
    except KeyError:
        raise ValueError(
            f"unknown simulator {simulator!r}; choose one of {sorted(SIMULATOR_FORMATS)}"
        ) from None
    missing = [k for k in spec if k not in draws.columns]
    if missing:
        raise ValueError(
            f"{simulator} needs {list(spec)}; the draws lack {missing} — use a "
            "Bekker sinkage posterior and a Janosi shear posterior (bekker+janosi)"
        )
    table = pd.DataFrame({name: draws[key].to_numpy() for key, (name, _) in spec.items()})
    stated = _stated(elastic_K, damping_R)
    for name, (value, _, _) in stated.items():
        table[name] = value
    return table


def _stated(elastic_K, damping_R) -> dict:
    given = {"elastic_K": elastic_K, "damping_R": damping_R}
    out = {}
    for name, value in given.items():
        default, unit, source = SCM_DEFAULTS[name]
        if value is not None and not value > 0:
            raise ValueError(f"{name} must be positive, got {value!r}")
        out[name] = (default, unit, source) if value is None else (value, unit, "stated by user")
    return out


def simulator_record(
    draws: pd.DataFrame,
    simulator: str = "chrono-scm",
    *,
    elastic_K: float | None = None,
    damping_R: float | None = None,
    support=None,
    context: dict | None = None,
) -> dict:
    """The JSON record beside a simulator's CSV (module docstring).

    ``support``: the :class:`~soilstats.bayes.support.SupportCheck` of the draws; ``context``:
    seed, soil, selection, version and any other facts of the run, copied in.
    """
    spec = SIMULATOR_FORMATS[simulator]
    stated = _stated(elastic_K, damping_R)
    record = {
        "simulator": simulator,
        "columns": {name: unit for _, (name, unit) in spec.items()}
        | {name: unit for name, (_, unit, _) in stated.items()},
        "stated_inputs": {
            name: {"value": value, "unit": unit, "source": source}
            for name, (value, unit, source) in stated.items()
        },
        "draws": len(draws),
        **(context or {}),
    }
    if support is not None:
        record["support"] = support.to_dict()
    notes = []
    width = negative_modulus_width(draws)
    if width is not None:
        share = float((draws["kc"] < 0).mean())
        record["negative_modulus_below_m"] = width
        notes.append(
            f"kc < 0 in {share:.0%} of the draws: Bekker's modulus kc/b + kphi turns negative "
            f"for contact widths below {width:.3g} m (99 % of draws); do not use these draws "
            "for narrower contacts"
        )
    stiff = int((draws["kphi"] >= stated["elastic_K"][0]).sum()) if "kphi" in draws else 0
    if stiff:
        notes.append(
            f"{stiff} draws have Bekker_Kphi >= elastic_K = {stated['elastic_K'][0]:g} Pa/m, "
            "which SCM requires to be larger; state a larger --scm-elastic-K"
        )
    record["notes"] = notes
    return record
