"""Ensemble-averaged pressure–sinkage curves: the classical literature's preprocessing.

Before Wong's graphical procedure, published Bevameter analyses (e.g. Oravec 2009 on GRC-1)
turn the repeats of one plate into a single curve: each repeat's sinkage z(p) is interpolated
onto a common pressure grid by a not-a-knot cubic spline, and the repeats are averaged point
by point. The averaged curve, not the measured samples, is then fitted. This module does that
step and nothing else; :mod:`soilstats.identification.classical` fits the curves.

The paper soilstats follows (Apfelbeck et al. 2011) fits the measured samples of every test
instead (Eq. 11), with per-test weights; docs/classical.md shows what the two give on GRC-1.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
from scipy.interpolate import CubicSpline

from ..errors import CampaignError, InputError

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign

__all__ = ["EnsembleCurve", "ensemble_curve"]

#: A not-a-knot cubic spline needs four samples (below that it has no interior knot).
MIN_SPLINE_SAMPLES = 4


@dataclass(frozen=True)
class EnsembleCurve:
    """The mean sinkage of several repeats on a common pressure grid.

    Attributes
    ----------
    b_m : float
        Plate size b [m] shared by the repeats (Eq. 7's b: radius of a circle).
    test_ids : tuple of str
        The repeats averaged.
    pressure_Pa : ndarray
        The grid [Pa], from 0 in equal steps.
    z_m, z_sd_m : ndarray
        Mean sinkage [m] of the repeats at each grid pressure, and their standard deviation
        (ddof = 1).
    sampled_max_Pa : float
        The smallest of the repeats' largest pressures [Pa]: above it at least one repeat is
        extrapolated by its spline (see :attr:`extrapolated`).
    dropped : dict
        test_id -> number of samples left out because their pressure did not exceed every
        earlier one (only with ``non_increasing="drop"``).
    """

    b_m: float
    test_ids: tuple[str, ...]
    pressure_Pa: np.ndarray
    z_m: np.ndarray
    z_sd_m: np.ndarray
    sampled_max_Pa: float
    dropped: dict

    @property
    def extrapolated(self) -> np.ndarray:
        """Mask of grid pressures above :attr:`sampled_max_Pa` (some repeat extrapolated)."""
        return self.pressure_Pa > self.sampled_max_Pa


def _rising_record(
    test_id: str, p: np.ndarray, z: np.ndarray, rows: np.ndarray, non_increasing: str, file: str
) -> tuple[np.ndarray, np.ndarray, int]:
    """The record with strictly rising pressure that a spline z(p) needs, and the count left
    out; ``file``: the sinkage file's name, for messages."""
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(z))):
        raise CampaignError(
            "an ensemble curve needs finite pressure and sinkage",
            file=file,
            test_id=test_id,
        )
    rising = np.diff(p) > 0
    if rising.all():
        return p, z, 0
    if non_increasing == "raise":
        first = int(np.flatnonzero(~rising)[0]) + 1
        raise CampaignError(
            f"pressure does not rise at file row {rows[first]} ({p[first]:g} Pa after "
            f"{p[first - 1]:g} Pa); a spline z(p) needs strictly rising pressure. Pass "
            "non_increasing='drop' to keep only the samples that set a new pressure maximum",
            file=file,
            column="force_N",
            test_id=test_id,
        )
    keep = p > np.concatenate([[-np.inf], np.maximum.accumulate(p)[:-1]])
    return p[keep], z[keep], int((~keep).sum())


def ensemble_curve(
    campaign: Campaign,
    test_ids: Iterable[str],
    *,
    p_max: float,
    step: float = 500.0,
    non_increasing: Literal["raise", "drop"] = "raise",
) -> EnsembleCurve:
    """Average the repeats ``test_ids`` of one plate onto the pressure grid 0, step, …, p_max.

    Parameters
    ----------
    campaign : Campaign
        Holds the records. They are used as loaded: pass ``quality="off"`` data to reproduce a
        published analysis (screening re-zeroes z at contact and removes spikes).
    test_ids : sequence of str
        Repeats of one plate (same ``b_m``), at least two.
    p_max : float
        Top of the grid [Pa] (Oravec's GRC-1 windows: 30–160 kPa).
    step : float, default 500
        Grid step [Pa] (0.5 kPa in Oravec 2009).
    non_increasing : {"raise", "drop"}
        A record whose pressure ever fails to rise raises a CampaignError naming the test and
        row; ``"drop"`` keeps the samples that set a new maximum and counts the rest.

    Returns
    -------
    EnsembleCurve
    """
    ids = tuple(str(t) for t in test_ids)
    if len(ids) < 2:
        raise InputError(f"an ensemble needs at least two repeats, got {list(ids)}")
    if not (p_max > 0 and step > 0):
        raise InputError(f"p_max and step must be positive, got {p_max!r}, {step!r}")
    log = campaign.tests.set_index("test_id").loc[list(ids)]
    sizes = log["b_m"].unique()
    if sizes.size != 1:
        raise InputError(f"the repeats {list(ids)} have different plate sizes b {sorted(sizes)}")
    grid = np.arange(0.0, p_max + step / 2.0, step)
    curves, tops, dropped = [], [], {}
    by_test = campaign.sinkage.groupby("test_id", sort=False)
    file = campaign.file_name("sinkage")
    for test_id in ids:
        record = by_test.get_group(test_id)
        p, z, left_out = _rising_record(
            test_id,
            record["pressure_Pa"].to_numpy(float),
            record["z_m"].to_numpy(float),
            record.index.to_numpy() + 1,
            non_increasing,
            file,
        )
        if p.size < MIN_SPLINE_SAMPLES:
            raise CampaignError(
                f"{p.size} samples with rising pressure; a not-a-knot spline needs "
                f"{MIN_SPLINE_SAMPLES}",
                file=file,
                test_id=test_id,
            )
        dropped[test_id] = left_out
        curves.append(CubicSpline(p, z, bc_type="not-a-knot", extrapolate=True)(grid))
        tops.append(p.max())
    stacked = np.vstack(curves)
    return EnsembleCurve(
        b_m=float(sizes[0]),
        test_ids=ids,
        pressure_Pa=grid,
        z_m=stacked.mean(axis=0),
        z_sd_m=stacked.std(axis=0, ddof=1),
        sampled_max_Pa=float(min(tops)),
        dropped=dropped,
    )
