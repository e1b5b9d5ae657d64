"""The frozen result of a posterior run: ArviZ data, diagnostics, a readable summary, draws."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import pandas as pd
import xarray as xr

from .._html import facts_html, notes_html, result_html, table_html
from ..errors import ConvergenceError, InputError, warn_renamed
from ..fitting.result import HealthFlag
from ..outputs import json_safe
from ..outputs.text import notes_block
from ._arviz import az
from .handout import hand_out
from .prior_sensitivity import THRESHOLD, influential_warning

if TYPE_CHECKING:
    from ..fitting.result import FitResult
    from .handout import Handout

__all__ = [
    "CONVERGENCE_CODES",
    "ESS_MIN",
    "RHAT_MAX",
    "PosteriorResult",
    "chain_diagnostics",
    "diagnose",
    "draws_converge",
]

#: Convergence thresholds (Vehtari et al. 2021, "Rank-normalization, folding, and
#: localization", Bayesian Analysis 16:667): R-hat ≤ 1.01 and bulk and tail ESS ≥ 400.
RHAT_MAX = 1.01
ESS_MIN = 400

#: The health codes of a posterior (``PosteriorResult.flags``), each a failed convergence
#: check: what it means and what to do in docs/posterior.md, "Convergence codes".
CONVERGENCE_CODES = ("high-r-hat", "low-bulk-ess", "low-tail-ess", "short-chain")


def chain_diagnostics(idata: Any, var_names: Iterable[str]) -> pd.DataFrame:
    """MCSE, bulk/tail ESS and R-hat of each of ``var_names`` (ArviZ's summary, unrounded)."""
    return az.summary(idata, var_names=list(var_names), kind="diagnostics", round_to="none")  # type: ignore[return-value]  # ArviZ: a DataFrame unless fmt='xarray'


def diagnose(table: pd.DataFrame) -> tuple[HealthFlag, ...]:
    """The failed convergence checks of an ArviZ summary table, one health flag per quantity
    and check (``high-r-hat``, ``low-bulk-ess``, ``low-tail-ess``); empty when all pass."""
    out = []
    for name, row in table.iterrows():
        if not row["r_hat"] <= RHAT_MAX:
            out.append(HealthFlag("high-r-hat", f"{name}: R-hat = {row['r_hat']:.4f} > {RHAT_MAX}"))
        if not row["ess_bulk"] >= ESS_MIN:
            out.append(
                HealthFlag("low-bulk-ess", f"{name}: ess bulk = {row['ess_bulk']:.0f} < {ESS_MIN}")
            )
        if not row["ess_tail"] >= ESS_MIN:
            out.append(
                HealthFlag("low-tail-ess", f"{name}: ess tail = {row['ess_tail']:.0f} < {ESS_MIN}")
            )
    return tuple(out)


def draws_converge(draws: dict[str, np.ndarray]) -> bool:
    """True when every array (chains, draws) passes R-hat ≤ 1.01 and bulk/tail ESS ≥ 400.

    The same rank-normalised split R-hat and ESS as :func:`arviz.summary` (and so as
    :func:`diagnose`); used while sampling to decide whether to run on.
    """
    ds = xr.Dataset({k: (("chain", "draw"), np.asarray(v)) for k, v in draws.items()})
    rhat = az.rhat(ds)
    bulk = az.ess(ds, method="bulk")
    tail = az.ess(ds, method="tail")
    return all(
        float(rhat[k]) <= RHAT_MAX and float(bulk[k]) >= ESS_MIN and float(tail[k]) >= ESS_MIN
        for k in draws
    )


@dataclass(frozen=True, eq=False)
class PosteriorResult:
    """Posterior of a soil model's parameters (see :func:`soilstats.bayes.sample_posterior`).

    Attributes
    ----------
    idata : arviz.InferenceData
        Groups ``posterior`` (parameters, SI units, φ in degrees; walkers as chains),
        ``sample_stats`` (``lp``), ``observed_data``, ``posterior_predictive`` and
        ``log_likelihood`` (so ``az.plot_ppc``, ``az.loo`` and ``az.compare`` apply), and for
        the population model ``constant_data`` (the measured curves); see
        :mod:`soilstats.bayes.predictive`.
    model_name : str
        Soil model (``"bekker"`` …), with ``kind`` ``"pooled"`` or ``"population"``.
    param_names : tuple of str
        The soil parameters whose draws :meth:`draws` returns.  For the population model
        these are the parameters of a *new* preparation of the soil.
    units : dict
        Unit of each parameter.
    var_names : tuple of str
        Every sampled quantity checked for convergence.
    flags : tuple of HealthFlag
        The failed convergence checks, each a code (:data:`CONVERGENCE_CODES`: R-hat > 1.01,
        bulk or tail ESS < 400, a kept chain shorter than 50 τ) with its message; empty when
        converged.  Was ``problems`` (the messages alone), which still works, with a
        ``FutureWarning``, until 0.3.0.
    sampler : dict
        Walkers, steps, burn-in, thinning, τ, acceptance, ``runtime_s`` (wall time [s]; also
        under its old name ``seconds`` until 0.3.0), evaluations.
    notes : tuple of str
        Model, likelihood and prior conventions, printed as numbered notes by :meth:`summary`.
    """

    # arviz.InferenceData: Any, as its groups (posterior, observed_data, …) are attributes
    # made at run time, which its type does not name.
    idata: Any
    model_name: str
    kind: str
    param_names: tuple[str, ...]
    units: dict[str, str]
    var_names: tuple[str, ...]
    flags: tuple[HealthFlag, ...]
    sampler: dict = field(repr=False)
    notes: tuple[str, ...] = ()
    lsq: FitResult | None = field(default=None, repr=False)  # the least-squares fit it began at
    #: Power-scaling prior sensitivity per quantity (:mod:`soilstats.bayes.prior_sensitivity`):
    #: to the default priors and to the user's; ``influential`` marks a default prior the
    #: draws rest on (also a DefaultWarning and a line of :meth:`summary`).
    prior_sensitivity: pd.DataFrame | None = field(default=None, repr=False, compare=False)
    # The chains' diagnostics when the sampler already computed them (its convergence check):
    # ArviZ's summary is the most expensive table here, so it is made once.
    _chains: pd.DataFrame | None = field(default=None, repr=False, compare=False)

    @property
    def converged(self) -> bool:
        """True when R-hat ≤ 1.01 and bulk/tail ESS ≥ 400 for every sampled quantity."""
        return not self.flags

    @property
    def problems(self) -> tuple[str, ...]:
        """Renamed :attr:`flags` (docs/conventions.md, "Renamed"): their messages."""
        warn_renamed("PosteriorResult.problems", "PosteriorResult.flags")
        return tuple(f.message for f in self.flags)

    def summary_table(
        self, prob: float = 0.9, handed_out: pd.DataFrame | None = None
    ) -> pd.DataFrame:
        """Mean, sd, ``prob`` equal-tailed interval, MCSE, bulk/tail ESS, R-hat per quantity.

        Parameters
        ----------
        prob : float
            Probability of the interval; its columns are named by it (``eti_5%``/``eti_95%``
            for 0.9).  Equal-tailed, not highest-density: an ETI maps through any monotone
            transform (k ↔ ln k), while the HDI of a right-skewed modulus spanning decades
            collapses onto its smallest draw (a review: k's 90 % HDI started at 1.7 N/m^(n+2),
            one draw with n < 0).
        handed_out : DataFrame, optional
            The draws a user is handed (the CLI's ``draws.csv``: inside the physical support).
            Mean, sd and interval of the handed-out parameters are then theirs; the
            diagnostics (MCSE, ESS, R-hat) stay those of the chains.
        """
        q = [(1 - prob) / 2, (1 + prob) / 2]
        lo, hi = (f"eti_{100 * x:.3g}%" for x in q)
        post = self.idata.posterior
        rows: dict[str, dict] = {}
        for name in self.var_names:
            use_kept = handed_out is not None and name in handed_out
            kept = cast(pd.DataFrame, handed_out)  # read where use_kept: not None
            x = kept[name].to_numpy() if use_kept else post[name].to_numpy().ravel()
            x = x[np.isfinite(x)]
            lower, upper = np.quantile(x, q) if x.size else (np.nan, np.nan)
            sd = float(np.std(x, ddof=1)) if x.size > 1 else np.nan
            rows[name] = {"mean": float(np.mean(x)), "sd": sd, lo: lower, hi: upper}
        stats = pd.DataFrame.from_dict(rows, orient="index")
        return stats.join(self._chain_diagnostics)

    @cached_property
    def _chain_diagnostics(self) -> pd.DataFrame:
        """MCSE, bulk/tail ESS and R-hat of every sampled quantity: the chains' own, whatever
        interval or draws a table describes, so computed once."""
        if self._chains is not None:
            return self._chains
        return chain_diagnostics(self.idata, self.var_names)

    @cached_property
    def diagnostics(self) -> pd.DataFrame:
        """:meth:`summary_table` at 90 %, computed once."""
        return self.summary_table(0.9)

    def interval(
        self, prob: float = 0.9, kind: str = "eti", *, allow_unconverged: bool = False
    ) -> pd.DataFrame:
        """Credible interval of each parameter: equal-tailed (``"eti"``) or HDI (``"hdi"``).

        Raises ConvergenceError for a posterior that did not converge, unless
        ``allow_unconverged`` (as :meth:`draws`)."""
        if not 0 < prob < 1:
            raise InputError(f"prob must be in (0, 1), got {prob!r}")
        d = self.draws(allow_unconverged=allow_unconverged)  # raises when not converged
        if kind == "hdi":
            hdi = az.hdi(self.idata, hdi_prob=prob, var_names=list(self.param_names))
            return pd.DataFrame(
                {n: hdi[n].to_numpy() for n in self.param_names}, index=["lower", "upper"]
            ).T
        if kind != "eti":
            raise InputError(f"kind must be 'eti' or 'hdi', got {kind!r}")
        q = [(1 - prob) / 2, (1 + prob) / 2]
        return d.quantile(q).T.set_axis(["lower", "upper"], axis=1)

    def draws(
        self, n: int | None = None, seed: int | None = None, *, allow_unconverged: bool = False
    ) -> pd.DataFrame:
        """Joint draws of the soil parameters, one row per draw (SI units, φ in degrees).

        Parameters
        ----------
        n : int, optional
            Number of rows, taken in a random order (without replacement when there are
            enough, with replacement otherwise).  By default all draws with the chains
            stacked: walker by walker, so neighbouring rows are autocorrelated — pass ``n``
            (e.g. ``len(result.draws())``) for rows in random order.
        seed : int, optional
            Seed of the subsampling.
        allow_unconverged : bool, default False
            Return the draws of a posterior that failed its convergence checks (to inspect
            them).  Without it such a posterior raises: its draws are not fit for a Monte
            Carlo.

        Raises
        ------
        ConvergenceError
            When the sampler did not converge (R-hat > 1.01 or ESS < 400 for some quantity;
            :attr:`flags` lists which), unless ``allow_unconverged``.
        """
        if self.flags and not allow_unconverged:
            failed = "; ".join(f.message for f in self.flags)
            raise ConvergenceError(
                f"the {self.model_name} {self.kind} posterior did not converge "
                f"({failed}): its draws are not fit for a rover Monte Carlo. "
                "Sample longer (draws=...), select one condition, or state priors; pass "
                "allow_unconverged=True to take them anyway",
                result=self,
            )
        post = self.idata.posterior
        table = pd.DataFrame({name: post[name].to_numpy().reshape(-1) for name in self.param_names})
        if n is None:
            return table
        rng = np.random.default_rng(seed)
        pick = rng.choice(len(table), size=n, replace=n > len(table))
        return table.iloc[pick].reset_index(drop=True)

    def to_dict(self, prob: float = 0.9) -> dict:
        """The JSON-ready content: per quantity mean, stderr (posterior sd), interval and
        diagnostics; convergence and its flags (``code``, ``message``; and, until 0.3.0, their
        messages under the old key ``problems``); units, sampler settings and notes."""
        table = self.summary_table(prob)
        return json_safe(
            {
                "model": self.model_name,
                "kind": self.kind,
                "params": {n: table.loc[n, "mean"] for n in self.param_names},
                "stderr": {n: table.loc[n, "sd"] for n in self.param_names},
                "units": dict(self.units),
                "converged": self.converged,
                "flags": [{"code": f.code, "message": f.message} for f in self.flags],
                "problems": [f.message for f in self.flags],  # the old key, until 0.3.0
                "diagnostics": table.reset_index(names="quantity").to_dict("records"),
                "sampler": dict(self.sampler),
                "notes": list(self.notes),
                "least_squares_health": self.least_squares_health(),
            }
        )

    def handout(self, contact_widths: tuple[float, float], *, seed: int | None = 0) -> Handout:
        """Whether this posterior's draws are fit for a rover Monte Carlo, and the draws a
        Monte Carlo may be given: :func:`soilstats.bayes.handout.hand_out` of this result
        alone (``contact_widths`` (b_min, b_max) [m]: where the draws will be used)."""
        return hand_out([self], contact_widths, seed=seed)

    def least_squares_health(self) -> list[dict]:
        """The health flags (``code``, ``message``) of the least-squares fit the sampler
        started from: its data-quality codes (bearing failure, spikes …) and the model's
        adequacy (lack-of-fit, test-scatter …) hold for the posterior too."""
        return [{"code": f.code, "message": f.message} for f in getattr(self.lsq, "flags", ())]

    def _sensitivity_lines(self) -> list[str]:
        """One line on the prior sensitivity (power-scaling), none where it was not checked."""
        table = self.prior_sensitivity
        if table is None or table.empty:
            return []
        warning = influential_warning(self.model_name, table)
        if warning is not None:
            return [f"Prior sensitivity: WARNING: {warning}"]
        worst = float(table["default_prior_sensitivity"].max())
        return [
            f"Prior sensitivity: the default priors are not influential (power-scaling "
            f"sensitivity {worst:.2g} <= {THRESHOLD:g} for every quantity)"
        ]

    def summary(self, prob: float = 0.9, handed_out: pd.DataFrame | None = None) -> str:
        """Readable report: estimates, ``prob`` interval, diagnostics, sampler and numbered
        notes; ``handed_out`` as in :meth:`summary_table`."""
        width = 92
        tab = self.summary_table(prob, handed_out)
        lo, hi = tab.columns[2], tab.columns[3]
        s = self.sampler
        lines = [
            f" {self.model_name} posterior ({self.kind}) ".center(width, "="),
            f"Sampler: emcee, {s['walkers']} walkers, {s['steps']} steps, burn-in {s['burn']}, "
            f"thin {s['thin']}, {s['kept']} draws kept, {s['runtime_s']:.2f} s"
            + (f" (run on {s['extended']}x to converge)" if s.get("extended") else ""),
            f"Autocorrelation time (steps): {s['tau_max']:.2f} (max over parameters); "
            f"acceptance {s['acceptance']:.2f}",
            "-" * width,
            f"{'quantity':>14} {'mean':>12} {'sd':>11} {lo + ' ':>12}{hi:>11} {'mcse':>9}"
            f" {'ess_bulk':>8} {'ess_tail':>8} {'r_hat':>6}",
        ]
        for name, r in tab.iterrows():
            lines.append(
                f"{name:>14} {r['mean']:>12.5g} {r['sd']:>11.4g} {r[lo]:>12.5g}{r[hi]:>11.5g}"
                f" {r['mcse_mean']:>9.3g} {r['ess_bulk']:>8.0f} {r['ess_tail']:>8.0f}"
                f" {r['r_hat']:>6.3f}"
            )
        lines.append("-" * width)
        if self.converged:
            lines.append(f"Convergence: OK (R-hat <= {RHAT_MAX}, bulk and tail ESS >= {ESS_MIN})")
        else:
            lines.append(
                f"Convergence: NOT CONVERGED — {len(self.flags)} failed check(s); "
                "do not use these draws (run longer: more draws)"
            )
            lines.extend(f"  ! {flag}" for flag in self.flags)
        lines += self._sensitivity_lines()
        units = ", ".join(f"{n} [{self.units[n]}]" for n in self.param_names)
        over = ""
        if handed_out is not None:
            post = self.idata.posterior
            total = post.sizes["chain"] * post.sizes["draw"]
            names = ", ".join(n for n in self.param_names if n in handed_out)
            over = (
                f" {names}: mean, sd and interval over the {len(handed_out)} draws handed out "
                f"(inside the physical support), of {total}; diagnostics over all."
            )
        notes = (
            f"Intervals are {prob:.0%} equal-tailed intervals; mcse is the Monte Carlo "
            f"standard error of the mean.{over}",
            f"Units: {units}.",
            *self.notes,
        )
        lines.extend(notes_block(notes))
        lines.append("=" * width)
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def _repr_html_(self) -> str:
        """The summary as tables, for notebooks: sampler, estimates with diagnostics,
        convergence (and every failed check), the least-squares start's health and the notes."""
        s = self.sampler
        facts = {
            "sampler": f"emcee, {s['walkers']} walkers, {s['steps']} steps, burn-in "
            f"{s['burn']}, {s['kept']} draws kept",
            "convergence": "OK"
            if self.converged
            else f"NOT CONVERGED ({len(self.flags)} failed checks): do not use these draws",
        }
        table = self.summary_table().rename_axis("quantity").reset_index()
        health = pd.DataFrame(self.least_squares_health())
        return result_html(
            f"{self.model_name} posterior ({self.kind})",
            facts_html(facts),
            table_html(table, caption="Estimates (90 % equal-tailed intervals) and diagnostics"),
            notes_html(self.flags, "Failed checks"),
            table_html(health, caption="Health of the least-squares start") if len(health) else "",
            notes_html(self.notes),
        )
