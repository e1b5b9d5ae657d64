"""The frozen result of an identification, with health flags and a readable summary."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Protocol

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike
from scipy.special import stdtrit

from ..errors import InputError
from ..outputs.files import json_safe
from ..outputs.text import notes_block

__all__ = ["FitResult", "HealthFlag", "epsilon"]

CORRELATION_LIMIT = 0.95


class NamedModel(Protocol):
    """What :meth:`FitResult.closed_form` reads of a model record (:class:`soilstats.Model`,
    a floor above fitting: docs/conventions.md, "Layers"); ``func`` and ``jac`` too where it
    has them."""

    @property
    def name(self) -> str: ...

    @property
    def param_names(self) -> tuple[str, ...]: ...

    @property
    def units(self) -> tuple[str, ...]: ...

    @property
    def bounds(self) -> tuple[tuple[float, float], ...]: ...


def epsilon(residuals: ArrayLike, y: ArrayLike, *, rss: float | None = None) -> float:
    """Fit quality ε = 1 − √(Σe²/(N−2)) / (Σ|y|/N) (Eq. 2); 1 is a perfect fit.

    ``rss`` = Σe² when the caller has it already (the optimiser does), else computed.
    """
    y = np.asarray(y, float)
    n = y.size
    if n <= 2:
        return np.nan
    if rss is None:
        residuals = np.asarray(residuals, float)
        rss = residuals @ residuals
    # np.add.reduce: ndarray.sum goes through a Python wrapper.
    return float(1.0 - np.sqrt(rss / (n - 2)) / (np.add.reduce(np.abs(y), axis=None) / n))


@dataclass(frozen=True)
class HealthFlag:
    """One failed health check: a short code and a sentence saying what it means."""

    code: str  # "not-converged", "outside-bounds", "high-correlation", "rank-deficient", …
    message: str

    def __str__(self) -> str:
        return f"[{self.code}] {self.message}"


@dataclass(frozen=True)
class FitResult:
    """Result of a weighted least-squares identification (paper Section 2, Eqs. 1–5).

    Attributes
    ----------
    values, stderr_values, covariance : numpy.ndarray
        The same numbers as ``params``, ``stderr``, ``cov`` without labels.
    params, stderr : pandas.Series
        Estimates θ̂ and their standard deviations σ = √diag Cov(θ̂) (Eq. 3), indexed by name.
    cov : pandas.DataFrame
        Cov(θ̂) = s²·(JᵀJ)⁻¹ with s² = Σ(w·e)²/(N − Np) (Eq. 4) and J = ∂(w·f)/∂θ (Eq. 5).
    epsilon : float
        Fit quality ε (Eq. 2), on the weighted residuals and data.
    rss : float
        Weighted residual sum of squares Σ(w·e)².
    dof : int
        N − Np.
    """

    model_name: str
    param_names: tuple[str, ...]
    values: np.ndarray  # θ̂ as a plain array (params is the named view)
    stderr_values: np.ndarray  # σ (Eq. 3)
    covariance: np.ndarray  # Cov(θ̂) (Eq. 4)
    epsilon: float
    rss: float
    nobs: int
    dof: int
    nfev: int
    niter: int
    converged: bool
    message: str
    units: dict[str, str]
    bounds: dict[str, tuple[float, float]]
    jacobian_method: str
    method: str = "Levenberg-Marquardt (weighted, Eq. 1)"
    condition_number: float = np.nan
    residuals: np.ndarray | None = field(default=None, repr=False)  # weighted w·(y − f)
    extra_flags: tuple[HealthFlag, ...] = ()
    #: Rows map parameter changes to the basis in which ``high-correlation`` is judged (None:
    #: the parameters themselves). A power law's scale and exponent are coupled by where
    #: z = 1 lies, not by the data; the identification judges each scale where the data measure it
    #: (soilstats.identification.centring).
    correlation_basis: np.ndarray | None = field(default=None, repr=False)
    notes: tuple[str, ...] = ()
    #: The model ``f(x, *θ)`` and its Jacobian ``jac(x, *θ) -> (N, p)`` (what :meth:`eval`
    #: and :meth:`eval_uncertainty` use; None for a result built without them).
    model_func: Callable | None = field(default=None, repr=False, compare=False)
    model_jac: Callable | None = field(default=None, repr=False, compare=False)

    @classmethod
    def closed_form(
        cls,
        model: NamedModel,
        values: ArrayLike,
        covariance: ArrayLike,
        weighted_residuals: ArrayLike,
        weighted_y: ArrayLike,
        *,
        name: str | None = None,
        method: str,
        message: str,
        condition_number: float = np.nan,
    ) -> FitResult:
        """Result of a non-iterative estimate (Wong's regressions, linear Mohr–Coulomb).

        ``model`` supplies names, units and bounds; ε (Eq. 2) and the RSS come from the
        weighted residuals and data, exactly as for the LM fits, so the two compare directly.
        """
        names = model.param_names
        covariance = np.asarray(covariance, float)
        resid = np.asarray(weighted_residuals, float)
        return cls(
            model_name=name or model.name,
            param_names=names,
            values=np.asarray(values, float),
            stderr_values=np.sqrt(np.diag(covariance)),
            covariance=covariance,
            epsilon=epsilon(resid, weighted_y),
            rss=float(resid @ resid),
            nobs=resid.size,
            dof=resid.size - len(names),
            nfev=0,
            niter=0,
            converged=True,
            message=message,
            units=dict(zip(names, model.units, strict=True)),
            bounds=dict(zip(names, model.bounds, strict=True)),
            jacobian_method="none",
            method=method,
            condition_number=condition_number,
            residuals=resid,
            model_func=getattr(model, "func", None),
            model_jac=getattr(model, "jac", None),
        )

    # -- named views, built on first use (pandas construction costs more than a whole fit) --
    @cached_property
    def _index(self) -> pd.Index:
        return pd.Index(self.param_names, dtype=object)

    @cached_property
    def params(self) -> pd.Series:
        """Estimates θ̂, indexed by parameter name."""
        return pd.Series(self.values, index=self._index, name="value")

    @cached_property
    def stderr(self) -> pd.Series:
        """Standard deviations σ = √diag Cov(θ̂) (Eq. 3), indexed by parameter name."""
        return pd.Series(self.stderr_values, index=self._index, name="stderr")

    @cached_property
    def cov(self) -> pd.DataFrame:
        """Covariance matrix Cov(θ̂) (Eq. 4), labelled by parameter name."""
        return pd.DataFrame(self.covariance, index=self._index, columns=self._index)

    @cached_property
    def corr(self) -> pd.DataFrame:
        """Correlation matrix of the estimates."""
        sd = self.stderr_values
        with np.errstate(invalid="ignore", divide="ignore"):
            c = self.covariance / np.outer(sd, sd)
        return pd.DataFrame(c, index=self.cov.index, columns=self.cov.columns)

    @property
    def judged_corr(self) -> np.ndarray:
        """The correlations ``high-correlation`` judges: in ``correlation_basis`` if set."""
        if self.correlation_basis is None:
            return self.corr.to_numpy()
        t = np.asarray(self.correlation_basis, float)
        cov = t @ self.covariance @ t.T
        sd = np.sqrt(np.diag(cov))
        with np.errstate(invalid="ignore", divide="ignore"):
            return cov / np.outer(sd, sd)

    @property
    def scale(self) -> float:
        """Residual variance s² = RSS/(N − Np) of the weighted residuals."""
        return self.rss / self.dof if self.dof > 0 else np.nan

    def conf_int(self, alpha: float = 0.05) -> pd.DataFrame:
        """Two-sided (1 − alpha) Student-t intervals θ̂ ± t(1−α/2, dof)·σ."""
        if not 0 < alpha < 1:
            raise InputError(f"alpha must be in (0, 1), got {alpha!r}")
        t = stdtrit(self.dof, 1 - alpha / 2)
        # Eq. 4's σ with the samples' degrees of freedom (a subclass's stderr may be another)
        sigma = pd.Series(self.stderr_values, index=self._index)
        return pd.DataFrame({"lower": self.params - t * sigma, "upper": self.params + t * sigma})

    # -- the fitted curve, as lmfit's ModelResult gives it --------------------------------
    def eval(self, x: ArrayLike) -> np.ndarray:
        """The fitted model f(x, θ̂) at the inputs ``x``, in the form the fit took them: sinkage
        z [m] (N,) for Bernstein, the (b [m], z [m]) rows (2, N) for Bekker and Reece, σ [Pa]
        for Mohr–Coulomb, (σ [Pa], j [m]) for Janosi–Hanamoto; pressure or stress in Pa."""
        if self.model_func is None:
            raise InputError(
                f"this {self.model_name} result carries no model to evaluate (it was built "
                "without one); fit it with soilstats.identify or a fit_* function"
            )
        return np.asarray(self.model_func(x, *self.values), dtype=float)

    def eval_uncertainty(self, x: ArrayLike, sigma: float = 1.0) -> np.ndarray:
        """``sigma`` standard deviations of the fitted curve at ``x`` (as :meth:`eval` takes
        it), from the parameter covariance by the delta method: sigma·√diag(J Cov Jᵀ), J the
        model's Jacobian at θ̂ (lmfit's ``ModelResult.eval_uncertainty``). Cov is Eq. 4's
        here; a fit over tests uses the test-level one (:class:`CampaignFit`)."""
        return self._band(x, sigma, self.covariance)

    def _band(self, x: ArrayLike, sigma: float, covariance: np.ndarray) -> np.ndarray:
        if self.model_jac is None:
            raise InputError(
                f"this {self.model_name} result carries no model Jacobian; fit it with "
                "soilstats.identify or a fit_* function"
            )
        if not sigma > 0:
            raise InputError(f"sigma must be positive, got {sigma!r}")
        jac = np.atleast_2d(np.asarray(self.model_jac(x, *self.values), dtype=float))
        variance = np.einsum("ij,jk,ik->i", jac, covariance, jac)
        return sigma * np.sqrt(np.maximum(variance, 0.0))

    @cached_property
    def flags(self) -> tuple[HealthFlag, ...]:
        """Every failed health check, with its reason (empty when the fit is healthy)."""
        out: list[HealthFlag] = []
        if not self.converged:
            out.append(
                HealthFlag("not-converged", f"the optimiser did not converge: {self.message}")
            )
        for name, value in self.params.items():
            lo, hi = self.bounds.get(name, (-np.inf, np.inf))
            if not lo <= value <= hi:
                out.append(
                    HealthFlag(
                        "outside-bounds",
                        f"{name} = {value:.4g} lies outside its physically plausible range "
                        f"({lo:g}, {hi:g})",
                    )
                )
        names = self.param_names
        corr = self.judged_corr
        for i in range(len(names)):
            for j in range(i + 1, len(names)):
                if abs(corr[i, j]) > CORRELATION_LIMIT:
                    out.append(
                        HealthFlag(
                            "high-correlation",
                            f"corr({names[i]}, {names[j]}) = {corr[i, j]:+.3f}: the data barely "
                            f"separate them; use their joint covariance, not the σ alone",
                        )
                    )
        out.extend(self.extra_flags)
        return tuple(out)

    @property
    def healthy(self) -> bool:
        return not self.flags

    def annotated(self, notes: Iterable[str] = (), flags: Iterable[HealthFlag] = ()) -> FitResult:
        """A copy with ``notes`` (str) and health ``flags`` (:class:`HealthFlag`) appended:
        what the caller knows about the data that the fit itself cannot see."""
        return replace(
            self, notes=self.notes + tuple(notes), extra_flags=self.extra_flags + tuple(flags)
        )

    # -- report ---------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """The JSON-ready content: estimates, stderr, units, ε, health and notes (NaN → None)."""

        return json_safe(
            {
                "model": self.model_name,
                "method": self.method,
                "params": dict(zip(self.param_names, self.values, strict=True)),
                "stderr": dict(zip(self.param_names, self.stderr_values, strict=True)),
                "units": self.units,
                "epsilon": self.epsilon,
                "converged": self.converged,
                "nobs": self.nobs,
                "health": [{"code": f.code, "message": f.message} for f in self.flags],
                "notes": self.notes,
            }
        )

    def _summary_parameters(self) -> list[str]:
        """The parameter lines of :meth:`summary`: value, σ (Eq. 3), relative σ, the 95 %
        t-interval and the unit."""
        lines = [
            f"{'param':>8} {'value':>14} {'stderr (Eq.3)':>14} {'rel.':>8} "
            f"{'95% CI (t)':>25}  unit"
        ]
        ci = self.conf_int(0.05)
        for name, v, s in zip(self.param_names, self.values, self.stderr_values, strict=True):
            rel = abs(s / v) if v != 0 else np.inf
            lines.append(
                f"{name:>8} {v:>14.6g} {s:>14.4g} {rel:>8.2%} "
                f"[{ci.loc[name, 'lower']:>11.5g},{ci.loc[name, 'upper']:>11.5g}]  "
                f"{self.units.get(name, '')}"
            )
        return lines

    def summary(self) -> str:
        """A fit report in the manner of lmfit and statsmodels, ending with numbered notes."""
        width = 78
        lines = [
            f" {self.model_name} fit ".center(width, "="),
            f"{'Method:':<18}{self.method}",
            f"{'Converged:':<18}{self.converged} ({self.message})",
            f"{'Observations:':<18}{self.nobs:<12d}{'Parameters:':<14}{len(self.params):<6d}"
            f"{'DoF:':<6}{self.dof}",
            f"{'Function evals:':<18}{self.nfev:<12d}{'Iterations:':<14}{self.niter}",
            f"{'epsilon (Eq. 2):':<18}{self.epsilon:<12.4f}{'Weighted RSS:':<14}{self.rss:.6g}",
            f"{'Jacobian:':<18}{self.jacobian_method:<12}{'cond(J):':<14}"
            f"{self.condition_number:.3g}",
            "-" * width,
            *self._summary_parameters(),
        ]
        if len(self.params) > 1:
            lines.append("-" * width)
            lines.append("Correlations:")
            names = self.param_names
            for i in range(len(names)):
                for j in range(i + 1, len(names)):
                    lines.append(f"  corr({names[i]}, {names[j]}) = {self.corr.iloc[i, j]:+.4f}")
        lines.append("-" * width)
        flags = self.flags
        lines.append("Health: OK" if not flags else f"Health: {len(flags)} flag(s)")
        lines.extend(f"  ! {flag}" for flag in flags)
        notes = (
            "Cov = s^2 (J^T J)^-1 with s^2 = sum (w e)^2 / (N - Np) (Eq. 4), J = d(w f)/dtheta "
            "(Eq. 5); stderr = sqrt(diag Cov) (Eq. 3).",
            "epsilon (Eq. 2) = 1 - sqrt(sum (w e)^2 / (N - 2)) / (sum |w y| / N), on the "
            "weighted data as in the paper's normalised pressures.",
            *self.notes,
        )
        lines.extend(notes_block(notes))
        lines.append("=" * width)
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def _parameter_table(self) -> pd.DataFrame:
        """Value, σ (Eq. 3), the 95 % interval and the unit of every parameter."""
        ci = self.conf_int(0.05)
        return pd.DataFrame(
            {
                "param": list(self.param_names),
                "value": [f"{v:.6g}" for v in self.values],
                "stderr (Eq. 3)": [f"{s:.4g}" for s in self.stderr_values],
                "95% CI (t)": [
                    f"[{ci.loc[n, 'lower']:.5g}, {ci.loc[n, 'upper']:.5g}]"
                    for n in self.param_names
                ],
                "unit": [self.units.get(n, "") for n in self.param_names],
            }
        )

    def _repr_html_(self) -> str:
        """The summary as tables, for notebooks."""
        from .._html import facts_html, notes_html, result_html, table_html

        facts = {
            "method": self.method,
            "converged": f"{self.converged} ({self.message})",
            "observations": self.nobs,
            "epsilon (Eq. 2)": f"{self.epsilon:.4f}",
        }
        health = [str(f) for f in self.flags] or ["OK"]
        return result_html(
            f"{self.model_name} fit",
            facts_html(facts),
            table_html(self._parameter_table()),
            notes_html(health, "Health"),
            notes_html(self.notes),
        )
