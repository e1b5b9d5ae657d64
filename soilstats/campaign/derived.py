"""Derived quantities of a campaign: plate geometry, pressure, ring stresses, deformation.

Pure, vectorised functions of NumPy arrays (or anything :func:`numpy.asarray` accepts), all in
SI units. Equation numbers are those of the paper the format follows: Eq. 6 (plate pressure),
Eq. 7 (Bekker's equation, whose b these functions provide), Eq. 12 (shear stress of a ring),
Eq. 14 (shear deformation). Where a quantity does not apply
(e.g. the area of a shear test's plate) the result is NaN.

:func:`add_test_columns` and :func:`add_sample_columns` append these quantities to the tables
of a validated campaign.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from .index import sample_test_positions

__all__ = [
    "add_sample_columns",
    "add_test_columns",
    "aspect_ratio",
    "bekker_b",
    "circle_area",
    "normal_pressure",
    "plate_area",
    "pressure",
    "rectangle_area",
    "ring_area",
    "ring_torque",
    "shear_deformation",
    "shear_stress",
]

ArrayLike = npt.ArrayLike
FloatArray = npt.NDArray[np.float64]


def _f(x: ArrayLike) -> FloatArray:
    return np.asarray(x, dtype=np.float64)


def _shape(shape: ArrayLike) -> npt.NDArray[np.object_]:
    return np.asarray(shape, dtype=object)


def circle_area(radius: ArrayLike) -> FloatArray:
    """Area of a circular plate, A = π r².

    Parameters
    ----------
    radius : array_like
        Plate radius r [m].

    Returns
    -------
    ndarray
        Area [m²].
    """
    r = _f(radius)
    return np.pi * r * r


def rectangle_area(width: ArrayLike, length: ArrayLike) -> FloatArray:
    """Area of a rectangular plate, A = w · l.

    Parameters
    ----------
    width, length : array_like
        Short side w and long side l [m].

    Returns
    -------
    ndarray
        Area [m²].
    """
    return _f(width) * _f(length)


def plate_area(
    shape: ArrayLike, radius: ArrayLike, width: ArrayLike, length: ArrayLike
) -> FloatArray:
    """Plate area by shape: π r² for ``"circle"``, w · l for ``"rectangle"``, else NaN.

    Parameters
    ----------
    shape : array_like of str
        ``"circle"`` or ``"rectangle"`` per test (anything else gives NaN).
    radius, width, length : array_like
        Radius r, short side w and long side l [m]; only the ones the shape uses are read.

    Returns
    -------
    ndarray
        Area A [m²].
    """
    s = _shape(shape)
    with np.errstate(invalid="ignore"):
        return np.where(
            s == "circle",
            circle_area(radius),
            np.where(s == "rectangle", rectangle_area(width, length), np.nan),
        )


def bekker_b(shape: ArrayLike, radius: ArrayLike, width: ArrayLike) -> FloatArray:
    """Bekker's plate dimension b (Eq. 7): the radius of a circle, the width of a rectangle.

    Parameters
    ----------
    shape : array_like of str
        ``"circle"`` or ``"rectangle"`` per test (anything else gives NaN).
    radius, width : array_like
        Radius r and short side w [m].

    Returns
    -------
    ndarray
        b [m].
    """
    s = _shape(shape)
    return np.where(s == "circle", _f(radius), np.where(s == "rectangle", _f(width), np.nan))


def aspect_ratio(shape: ArrayLike, width: ArrayLike, length: ArrayLike) -> FloatArray:
    """Plate aspect ratio l / w: 1 for a circle, length over width for a rectangle.

    Parameters
    ----------
    shape : array_like of str
        ``"circle"`` or ``"rectangle"`` per test (anything else gives NaN).
    width, length : array_like
        Short side w and long side l [m].

    Returns
    -------
    ndarray
        Aspect ratio [-], ≥ 1 for a valid campaign.
    """
    s = _shape(shape)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = _f(length) / _f(width)
    return np.where(s == "circle", 1.0, np.where(s == "rectangle", ratio, np.nan))


def pressure(force: ArrayLike, area: ArrayLike) -> FloatArray:
    """Plate pressure p = F / A (Eq. 6).

    Parameters
    ----------
    force : array_like
        Force normal to the plate F [N]; negative readings stay negative.
    area : array_like
        Plate area A [m²].

    Returns
    -------
    ndarray
        Pressure p [Pa].
    """
    return _f(force) / _f(area)


def ring_area(r_inner: ArrayLike, r_outer: ArrayLike) -> FloatArray:
    """Contact area of a shear ring, A = π (r_o² − r_i²).

    Parameters
    ----------
    r_inner, r_outer : array_like
        Inner radius r_i and outer radius r_o [m].

    Returns
    -------
    ndarray
        Ring area [m²].
    """
    ri, ro = _f(r_inner), _f(r_outer)
    return np.pi * (ro * ro - ri * ri)


def normal_pressure(normal_force: ArrayLike, r_inner: ArrayLike, r_outer: ArrayLike) -> FloatArray:
    """Normal pressure under a shear ring, σ = N / (π (r_o² − r_i²)).

    Parameters
    ----------
    normal_force : array_like
        Normal force on the ring N [N].
    r_inner, r_outer : array_like
        Inner radius r_i and outer radius r_o [m].

    Returns
    -------
    ndarray
        Normal pressure σ [Pa].
    """
    return _f(normal_force) / ring_area(r_inner, r_outer)


def shear_stress(torque: ArrayLike, r_inner: ArrayLike, r_outer: ArrayLike) -> FloatArray:
    """Shear stress of a ring from its torque, τ = 3 T / (2π (r_o³ − r_i³)) (Eq. 12).

    This assumes τ uniform over the ring's annulus: T = ∫ τ r · 2π r dr from r_i to r_o.

    Parameters
    ----------
    torque : array_like
        Measured torque T [N m].
    r_inner, r_outer : array_like
        Inner radius r_i and outer radius r_o [m].

    Returns
    -------
    ndarray
        Shear stress τ [Pa].
    """
    ri, ro = _f(r_inner), _f(r_outer)
    return 3.0 * _f(torque) / (2.0 * np.pi * (ro**3 - ri**3))


def ring_torque(tau: ArrayLike, r_inner: ArrayLike, r_outer: ArrayLike) -> FloatArray:
    """Torque of a ring under uniform shear stress, T = τ·2π(r_o³ − r_i³)/3 (Eq. 12 inverted).

    Parameters
    ----------
    tau : array_like
        Shear stress τ [Pa].
    r_inner, r_outer : array_like
        Inner radius r_i and outer radius r_o [m].

    Returns
    -------
    ndarray
        Torque T [N m].
    """
    ri, ro = _f(r_inner), _f(r_outer)
    return _f(tau) * 2.0 * np.pi * (ro**3 - ri**3) / 3.0


def shear_deformation(angle: ArrayLike, r_inner: ArrayLike, r_outer: ArrayLike) -> FloatArray:
    """Shear deformation at the mean ring radius, j = (r_o + r_i)/2 · α (Eq. 14).

    Parameters
    ----------
    angle : array_like
        Rotation angle α of the ring since the start of the test [rad].
    r_inner, r_outer : array_like
        Inner radius r_i and outer radius r_o [m].

    Returns
    -------
    ndarray
        Shear deformation j [m].
    """
    return 0.5 * (_f(r_outer) + _f(r_inner)) * _f(angle)


def _col(frame: pd.DataFrame, name: str) -> FloatArray:
    # Conditional columns may be absent (e.g. no rectangle in the campaign): read as NaN.
    if name in frame.columns:
        return frame[name].to_numpy(dtype=np.float64, na_value=np.nan)
    return np.full(len(frame), np.nan)


def add_test_columns(tests: pd.DataFrame, n_samples: ArrayLike) -> pd.DataFrame:
    """Return a copy of a validated log with the derived test columns appended.

    Adds ``b_m``, ``area_m2``, ``aspect_ratio`` (sinkage tests), ``ring_area_m2`` (shear
    tests) and ``n_samples``; NaN where a quantity does not apply.

    Parameters
    ----------
    tests : DataFrame
        Validated log (typed columns).
    n_samples : array_like of int
        Number of samples of each test, in the order of ``tests``.

    Returns
    -------
    DataFrame
        New frame; ``tests`` is not modified.
    """
    out = tests.copy()
    kind = out["kind"].to_numpy(dtype=object)
    # Shape is only meaningful for sinkage tests (a shear test may carry a stray value).
    shape: Any = np.full(len(out), None, dtype=object)  # object array (numpy's stubs: where)
    if "shape" in out.columns:
        shape = np.where(kind == "sinkage", out["shape"].to_numpy(dtype=object), None)  # type: ignore[call-overload]  # numpy's stubs: where(cond, x, None) is valid
    radius, width, length = _col(out, "radius_m"), _col(out, "width_m"), _col(out, "length_m")
    out["b_m"] = bekker_b(shape, radius, width)
    out["area_m2"] = plate_area(shape, radius, width, length)
    out["aspect_ratio"] = aspect_ratio(shape, width, length)
    ring = ring_area(_col(out, "r_inner_m"), _col(out, "r_outer_m"))
    out["ring_area_m2"] = np.where(kind == "shear", ring, np.nan)
    out["n_samples"] = np.asarray(n_samples, dtype=np.int64)
    return out


def _per_sample(tests: pd.DataFrame, rows: npt.NDArray[np.intp], column: str) -> FloatArray:
    # The test's value for every sample row (every sample's test is in the log).
    return _col(tests, column)[rows]


def add_sample_columns(
    tests: pd.DataFrame, sinkage: pd.DataFrame, shear: pd.DataFrame
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Return copies of the sample tables with their derived columns appended.

    Sinkage gets ``pressure_Pa`` (Eq. 6); shear gets ``sigma_Pa``, ``tau_Pa`` (Eq. 12) and
    ``j_m`` (Eq. 14).

    Parameters
    ----------
    tests : DataFrame
        Validated log with the derived test columns (:func:`add_test_columns`).
    sinkage, shear : DataFrame
        Validated sample tables.

    Returns
    -------
    (DataFrame, DataFrame)
        New sinkage and shear frames.
    """
    sink = sinkage.copy()
    sink["pressure_Pa"] = pressure(
        sink["force_N"].to_numpy(dtype=np.float64),
        _per_sample(tests, sample_test_positions(sink["test_id"], tests["test_id"]), "area_m2"),
    )
    shr = shear.copy()
    rows = sample_test_positions(shr["test_id"], tests["test_id"])
    ri, ro = _per_sample(tests, rows, "r_inner_m"), _per_sample(tests, rows, "r_outer_m")
    shr["sigma_Pa"] = normal_pressure(shr["normal_force_N"].to_numpy(dtype=np.float64), ri, ro)
    shr["tau_Pa"] = shear_stress(shr["torque_Nm"].to_numpy(dtype=np.float64), ri, ro)
    shr["j_m"] = shear_deformation(shr["angle_rad"].to_numpy(dtype=np.float64), ri, ro)
    return sink, shr
