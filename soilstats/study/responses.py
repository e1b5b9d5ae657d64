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

import numpy as np
import pandas as pd

from ..identification import fit_per_test

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

    def __init__(self, campaign, *, progress: bool = False) -> None:
        self.campaign = campaign
        self.progress = progress
        self._fits: dict[str, pd.DataFrame] = {}
        self.warnings: list[str] = []

    def fits(self, kind: str, test_ids) -> pd.DataFrame:
        """Rows of :func:`soilstats.fit_per_test` for ``test_ids`` (fitting those not yet done)."""
        ids = [str(t) for t in test_ids]
        done = self._fits.get(kind)
        have = set() if done is None else set(done["test_id"])
        missing = [t for t in ids if t not in have]
        if missing:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                new = fit_per_test(
                    self.campaign, kind, progress=self.progress, test_id=list(missing)
                )
            # A failed per-test fit keeps its row (NaN) and is stated in the report.
            self.warnings += [str(w.message) for w in caught]
            done = new if done is None else pd.concat([done, new], ignore_index=True)
            self._fits[kind] = done
        table = done.set_index("test_id").loc[ids].reset_index()
        return table

    def fill(self, *, jobs: int | None = 1, chunks_per_job: int = 4) -> None:
        """Fit every test of the campaign now, spread over ``jobs`` workers in chunks of
        tests (each test's fit depends on its own samples only, so the rows are the ones
        :meth:`fits` would compute one study at a time)."""
        from ..parallel import effective_jobs, parallel_map

        tests = self.campaign.tests
        chunks = []
        for kind in ("sinkage", "shear"):
            ids = [str(t) for t in tests.loc[tests["kind"] == kind, "test_id"]]
            have = set() if self._fits.get(kind) is None else set(self._fits[kind]["test_id"])
            ids = [t for t in ids if t not in have]
            if not ids:
                continue
            n_parts = min(len(ids), max(1, effective_jobs(jobs) * chunks_per_job))
            parts = [list(p) for p in np.array_split(np.array(ids, dtype=object), n_parts)]
            pieces = self.campaign.partition(parts)  # one pass, not a select per part
            chunks += [(piece, kind, part) for piece, part in zip(pieces, parts, strict=True)]
        for kind, fitted, caught in parallel_map(_fit_chunk, chunks, jobs=jobs):
            self.warnings += caught
            done = self._fits.get(kind)
            self._fits[kind] = (
                fitted if done is None else pd.concat([done, fitted], ignore_index=True)
            )

    def sinkage(self, test_ids, z_ref_m: float, z_window_m: float) -> pd.DataFrame:
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

    def shear(self, test_ids) -> pd.DataFrame:
        """Per-test shear responses: sigma_mean_Pa, tau_ss_Pa (NaN if never steady), steady."""
        return self.fits("shear", test_ids)


def _fit_chunk(task) -> tuple[str, pd.DataFrame, list[str]]:
    """Per-test fits of one chunk of tests, with the warnings they raised (a worker task)."""
    campaign, kind, ids = task
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fitted = fit_per_test(campaign, kind, test_id=ids)
    return kind, fitted, [str(w.message) for w in caught]
