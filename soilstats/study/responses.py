"""Per-test responses of a study: one row per test, one column per identified quantity.

Sinkage tests (one plate each) give Bernstein's ``k`` and ``n`` (Eq. 8, from
:func:`soilstats.fit_per_test`) and the measured pressure at a reference sinkage; shear tests
give the mean normal pressure σ and the steady-state shear stress τ_ss, the data points of
the Mohr–Coulomb line (Eq. 15).  Columns added here:

* ``log10_k`` — log10 of k [k in N/m^(n+2)]; scatter of soil stiffness is multiplicative;
* ``p_ref_Pa`` — mean measured pressure (Eq. 6) of the samples within ±``z_window_m`` of
  ``z_ref_m``; ``log10_p_ref`` its log10 (a difference of 0.06 is a factor 1.15);
* ``sigma_mean_Pa``, ``tau_ss_Pa`` (shear) as :func:`soilstats.fit_per_test` gives them.

:class:`PerTestCache` fits each test once, so ``python -m soilstats.study all`` does not
refit the tests that several studies share.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from typing import TYPE_CHECKING, Literal, cast

import numpy as np
import pandas as pd

from ..errors import ConvergenceWarning
from ..identification import fit_per_test
from ..kinds import TEST_KINDS

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign

__all__ = ["PerTestCache", "pressure_at"]


def pressure_at(sinkage: pd.DataFrame, z_ref_m: float, z_window_m: float) -> pd.Series:
    """Mean measured pressure [Pa] per test over z_ref ± window (NaN if the test stops short)."""
    near = sinkage[(sinkage["z_m"] - z_ref_m).abs() <= z_window_m]
    return near.groupby("test_id", sort=False)["pressure_Pa"].mean()


class PerTestCache:
    """Per-test fits of one campaign, computed on demand and kept.

    Parameters
    ----------
    campaign : Campaign
    progress : bool
        tqdm progress bars while fitting.
    """

    def __init__(self, campaign: Campaign, *, progress: bool = False) -> None:
        self.campaign = campaign
        self.progress = progress
        self._fits: dict[str, pd.DataFrame] = {}

    def fits(self, kind: str, test_ids: Iterable[str]) -> pd.DataFrame:
        """Rows of :func:`soilstats.fit_per_test` for ``test_ids`` (fitting those not yet done).

        A fit that did not converge keeps its row (NaN, ``converged`` False); the study
        states it for its own tests (:func:`~soilstats.identification.per_test
        .not_converged_message`), whichever study or worker happened to fit them first.
        """
        ids = [str(t) for t in test_ids]
        done = self._fits.get(kind)
        have = set() if done is None else set(done["test_id"])
        missing = [t for t in ids if t not in have]
        if missing:
            self._fit(kind, missing, jobs=1)
        table = self._fits[kind].set_index("test_id").loc[ids].reset_index()
        return table

    def fill(self, *, jobs: int | None = 1) -> None:
        """Fit every test of the campaign now, over ``jobs`` workers (each test's fit depends
        on its own samples only, so the rows are the ones :meth:`fits` would compute one
        study at a time)."""
        tests = self.campaign.tests
        for kind in TEST_KINDS:
            have = set() if self._fits.get(kind) is None else set(self._fits[kind]["test_id"])
            ids = [str(t) for t in tests.loc[tests["kind"] == kind, "test_id"]]
            ids = [t for t in ids if t not in have]
            if ids:
                self._fit(kind, ids, jobs=jobs)

    def _fit(self, kind: str, ids: list[str], *, jobs: int | None) -> None:
        with warnings.catch_warnings():
            # Stated per study, from the rows (see fits), not once by whoever fitted them.
            warnings.simplefilter("ignore", ConvergenceWarning)
            new = fit_per_test(
                self.campaign,
                cast(Literal["sinkage", "shear"], kind),
                progress=self.progress,
                jobs=jobs,
                test_id=ids,
            )
        done = self._fits.get(kind)
        self._fits[kind] = new if done is None else pd.concat([done, new], ignore_index=True)

    def sinkage(self, test_ids: Iterable[str], z_ref_m: float, z_window_m: float) -> pd.DataFrame:
        """Per-test sinkage responses: Bernstein k, n, log10_k, p_ref_Pa, log10_p_ref."""
        table = self.fits("sinkage", test_ids)
        samples = self.campaign.sinkage
        samples = samples[samples["test_id"].isin(set(table["test_id"]))]
        p_ref = pressure_at(samples, z_ref_m, z_window_m)
        table["p_ref_Pa"] = table["test_id"].map(p_ref).astype(float)
        with np.errstate(invalid="ignore", divide="ignore"):
            table["log10_k"] = np.log10(table["k"].where(table["k"] > 0))
            table["log10_p_ref"] = np.log10(table["p_ref_Pa"].where(table["p_ref_Pa"] > 0))
        return table

    def shear(self, test_ids: Iterable[str]) -> pd.DataFrame:
        """Per-test shear responses: sigma_mean_Pa, tau_ss_Pa (NaN if never steady), steady."""
        return self.fits("shear", test_ids)
