"""Names for readers: parameter symbols with units, column names in words, natural order.

Results keep their machine names (``kphi``, ``velocity_m_s``, ``log10_p_ref``); reports show
these labels instead, so a table header reads "k_φ (Pa/m^n)" and "velocity (m/s)", and
levels sort as a person counts (1, 2, 10 — not 1, 10, 2).
"""

from __future__ import annotations

from collections.abc import Iterable

from .._text import natural_key
from ..models import MODELS
from .document import Markup, esc, math

__all__ = [
    "column_label",
    "natural_key",
    "natural_sorted",
    "parameter_label",
    "parameter_symbol",
    "unit_text",
]

# Typst math of what is no model parameter; those of the parameters are the model records'
# (``Model.labels``: models/sinkage.py, models/shear.py, or one's own).
_SYMBOLS = {"epsilon": "epsilon"}


def _symbol(name: str) -> str | None:
    """Typst math of a parameter: the first registered model to label it says how."""
    for model in MODELS.values():
        label = model.label_of.get(name)
        if label is not None:
            return label.symbol
    return _SYMBOLS.get(name)


# Column names whose words are not their parts.
_COLUMNS = {
    "b_m": "plate width b (m)",
    "radius_m": "plate radius (m)",
    "velocity_m_s": "penetration velocity (m/s)",
    "shear_velocity_m_s": "shear velocity (m/s)",
    "log10_p_ref": "log₁₀ pressure at z_ref",
    "p_ref_Pa": "pressure at z_ref (Pa)",
    "tau_ss_Pa": "steady-state shear stress τ_ss (Pa)",
    "sigma_mean_Pa": "mean normal pressure σ (Pa)",
    "phi_deg": "friction angle φ (°)",
    "c_Pa": "cohesion c (Pa)",
    "K_m": "shear modulus K (m)",
    "z_max_m": "maximum sinkage (m)",
    "r_inner_m": "inner ring radius (m)",
    "r_outer_m": "outer ring radius (m)",
    "grouser_height_m": "grouser height (m)",
    "n_grousers": "number of grousers",
    "test_id": "test",
    "p_value": "p",
    "p_adjusted": "p (Holm)",
    "p_adj": "p (Tukey)",
    "stderr": "σ",
    "n_tests": "tests",
}

# Unit suffixes of the campaign format (docs/campaign-format.md), longest first.
_UNITS = (
    ("_mm_s", "mm/s"),
    ("_m_s", "m/s"),
    ("_kPa", "kPa"),
    ("_Pa", "Pa"),
    ("_deg", "°"),
    ("_mm", "mm"),
    ("_Nm", "N·m"),
    ("_N", "N"),
    ("_m", "m"),
    ("_s", "s"),
    ("_kg", "kg"),
)


def natural_sorted(values: Iterable[object]) -> list:
    """``values`` in natural order (see :func:`natural_key`)."""
    return sorted(values, key=natural_key)


def parameter_symbol(name: str) -> Markup:
    """A model parameter as typeset mathematics (``kphi`` → k_φ)."""
    symbol = _symbol(name)
    return math(symbol or (name if name.isidentifier() and len(name) == 1 else f'"{name}"'))


def unit_text(unit: str) -> str:
    """A unit string as printed (``Pa/m^(n-1)`` stays; empty stays empty)."""
    return "°" if unit == "deg" else unit


def parameter_label(name: str, unit: str = "") -> Markup:
    """Symbol and unit, e.g. ``k_φ (Pa/m^n)``; dimensionless parameters get no unit."""
    label = parameter_symbol(name)
    unit = unit_text(unit or "")
    return label + (esc(f" ({unit})") if unit and unit != "-" else Markup(""))


def column_label(name: str) -> str:
    """A column name in words with its unit: ``velocity_m_s`` → "penetration velocity (m/s)"."""
    if name in _COLUMNS:
        return _COLUMNS[name]
    for suffix, unit in _UNITS:
        if name.endswith(suffix) and len(name) > len(suffix):
            return f"{name[: -len(suffix)].replace('_', ' ')} ({unit})"
    return name.replace("_", " ")
