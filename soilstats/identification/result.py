"""``CampaignFit``: a least-squares fit of pooled campaign tests, with the tests it used."""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np
import pandas as pd

from ..fitting.result import FitResult, HealthFlag
from ..report.files import json_safe
from .bootstrap import TestBootstrap

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
    bootstrap: TestBootstrap | None = field(default=None, repr=False)

    @classmethod
    def of(
        cls,
        fit: FitResult,
        tests: pd.DataFrame,
        notes=(),
        flags: tuple[HealthFlag, ...] | list[HealthFlag] = (),
        bootstrap: TestBootstrap | None = None,
    ) -> CampaignFit:
        """``fit`` with the tests it used, the notes and flags of the pooling, and the
        test-level bootstrap with the flags it raises."""
        notes, flags = list(notes), list(flags)
        if bootstrap is not None:
            more_notes, more_flags = _bootstrap_findings(fit, bootstrap)
            notes += more_notes
            flags += more_flags
        base = fit.annotated(notes, flags)
        fields_ = {f.name: getattr(base, f.name) for f in fields(FitResult)}
        return cls(**fields_, tests=tests, bootstrap=bootstrap)

    @property
    def stderr_tests(self) -> pd.Series | None:
        """Test-level standard errors (cluster bootstrap over tests), or None if not run."""
        return None if self.bootstrap is None else self.bootstrap.stderr

    @property
    def n_tests(self) -> int:
        """Tests that contributed samples to the fit."""
        if self.tests is None:
            return 0
        if "used" in self.tests.columns:
            return int((self.tests["used"].to_numpy() > 0).sum())
        return len(self.tests)

    def to_dict(self) -> dict:
        out = super().to_dict() | {"tests": self.n_tests, "stderr_tests": None}
        if self.bootstrap is not None:
            out["stderr_tests"] = json_safe(dict(self.stderr_tests))
        return out

    def summary(self) -> str:
        text = super().summary()
        if self.bootstrap is None:
            return text
        bs = self.bootstrap
        lines = [
            f"Test-level stderr (cluster bootstrap: {bs.n_resamples} resamples of "
            f"{bs.n_tests} tests, seed {bs.seed}, {bs.n_failed} not converged):"
        ]
        ratio = self.stderr_tests / self.stderr
        lines += [
            f"  {name:>8} {self.stderr_tests[name]:>14.4g}   {ratio[name]:.2f} × Eq. 4"
            for name in self.param_names
        ]
        head, _, tail = text.rpartition("Health:")
        return head + "\n".join(lines) + "\nHealth:" + tail


#: Eq. 4's σ and the test-level σ disagree beyond this factor (either way): flag it.
DISAGREEMENT = 2.0
#: More resamples than this share not converging: the test-level σ is not to be trusted.
MAX_FAILED_SHARE = 0.05


def _bootstrap_findings(fit: FitResult, bs: TestBootstrap) -> tuple[list[str], list[HealthFlag]]:
    notes = [
        f"stderr_tests: sd of the estimates over {bs.n_resamples} resamples of the "
        f"{bs.n_tests} tests (cluster bootstrap, seed {bs.seed}); Eq. 4's stderr assumes "
        "independent samples."
    ]
    flags = []
    ratio = (bs.stderr / fit.stderr).to_numpy()
    off = [
        f"{name} {r:.2g}×"
        for name, r in zip(fit.param_names, ratio, strict=True)
        if np.isfinite(r) and not 1 / DISAGREEMENT <= r <= DISAGREEMENT
    ]
    if off:
        flags.append(
            HealthFlag(
                "test-scatter",
                "the test-level stderr differs from Eq. 4's by more than "
                f"{DISAGREEMENT:g}× ({', '.join(off)}): the tests scatter more than their "
                "samples say; quote stderr_tests, not stderr",
            )
        )
    if bs.n_failed > MAX_FAILED_SHARE * bs.n_resamples:
        flags.append(
            HealthFlag(
                "bootstrap-unstable",
                f"{bs.n_failed} of {bs.n_resamples} resamples of the tests did not converge: "
                "the estimate depends on which tests are in the campaign",
            )
        )
    return notes, flags
