"""``CampaignFit``: a least-squares fit of pooled campaign tests, with the tests it used."""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import pandas as pd

from ..fitting.result import FitResult, HealthFlag

__all__ = ["CampaignFit"]


@dataclass(frozen=True)
class CampaignFit(FitResult):
    """A :class:`~soilstats.fitting.FitResult` of pooled tests (Section 2.1) plus ``tests``.

    ``tests`` has one row per test considered: ``test_id``, the samples it had and used, its
    weight, and why it was left out (``problem``); the columns differ for sinkage and shear
    (see :func:`~soilstats.identification.pool_sinkage`, :func:`~.pool_shear`).  The fitting
    layer knows nothing of campaigns; this is where the two meet.
    """

    tests: pd.DataFrame | None = field(default=None, repr=False)

    @classmethod
    def of(
        cls,
        fit: FitResult,
        tests: pd.DataFrame,
        notes=(),
        flags: tuple[HealthFlag, ...] | list[HealthFlag] = (),
    ) -> CampaignFit:
        """``fit`` with the tests it used, and the notes and flags of the pooling."""
        base = fit.annotated(notes, flags)
        return cls(**{f.name: getattr(base, f.name) for f in fields(FitResult)}, tests=tests)

    @property
    def n_tests(self) -> int:
        """Tests that contributed samples to the fit."""
        if self.tests is None:
            return 0
        if "used" in self.tests.columns:
            return int((self.tests["used"].to_numpy() > 0).sum())
        return len(self.tests)

    def to_dict(self) -> dict:
        return super().to_dict() | {"tests": self.n_tests}
