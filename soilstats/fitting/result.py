"""The frozen result of an identification, with health flags; its text and HTML views in
soilstats.fitting.summary."""

from __future__ import annotations

import inspect
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any, Protocol

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike
from scipy.special import stdtrit

from ..errors import InputError
from ..outputs.files import json_safe
from .summary import fit_html, fit_summary, parameter_frame, parameter_lines

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


def input_names_of(model: object) -> tuple[str, ...]:
    """Short names of a model's inputs: a model record's ``inputs`` without their units
    (``"b [m]"`` -> ``"b"``), else the first argument of a plain ``f(x, *params)``."""
    inputs = getattr(model, "inputs", None)
    if inputs:
        return tuple(str(i).split()[0] for i in inputs)
    args = function_arguments(model)
    return args[:1]


def function_arguments(func: object) -> tuple[str, ...]:
    """The positional argument names of ``func`` (empty when it has none to read, or takes
    ``*args``): ``lambda x, a, b: …`` -> ``("x", "a", "b")``."""
    try:
        sig = inspect.signature(func)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return ()
    names = []
    for p in sig.parameters.values():
        if p.kind not in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD):
            return ()  # *args: the parameters have no names to read
        names.append(p.name)
    return tuple(names)


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
    #: Short names of the rows of ``x`` (``("b", "z")`` for Bekker, ``("x",)`` for a plain
    #: ``f(x, a, b)``): the keywords :meth:`eval` takes. Empty: unnamed.
    input_names: tuple[str, ...] = ()
    #: The inputs and measurements the fit was made on (what :meth:`plot_fit` draws; None for
    #: a result built without them).
    x_data: np.ndarray | None = field(default=None, repr=False, compare=False)
    y_data: np.ndarray | None = field(default=None, repr=False, compare=False)

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
        x: ArrayLike | None = None,
        y: ArrayLike | None = None,
    ) -> FitResult:
        """Result of a non-iterative estimate (Wong's regressions, linear Mohr–Coulomb).

        ``model`` supplies names, units and bounds; ε (Eq. 2) and the RSS come from the
        weighted residuals and data, exactly as for the LM fits, so the two compare directly.
        ``x`` and ``y``: the unweighted inputs and measurements (for :meth:`plot_fit`).
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
            input_names=input_names_of(model),
            x_data=None if x is None else np.asarray(x, float),
            y_data=None if y is None else np.asarray(y, float).ravel(),
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

    # -- lmfit's goodness-of-fit statistics (its definitions, on the weighted residuals) -----
    @property
    def chisqr(self) -> float:
        """χ² = Σ(w·e)², the weighted RSS (lmfit's ``chisqr``)."""
        return self.rss

    @property
    def redchi(self) -> float:
        """Reduced χ² = χ²/(N − Np) (lmfit's ``redchi``; :attr:`scale`)."""
        return self.scale

    @property
    def aic(self) -> float:
        """Akaike's criterion N·ln(χ²/N) + 2·Np, as lmfit defines it (lower is better;
        only differences between fits of the same data mean anything)."""
        n, k = self.nobs, len(self.param_names)
        return float(n * np.log(self.rss / n) + 2 * k) if self.rss > 0 else -np.inf

    @property
    def bic(self) -> float:
        """Bayesian criterion N·ln(χ²/N) + ln(N)·Np, as lmfit defines it."""
        n, k = self.nobs, len(self.param_names)
        return float(n * np.log(self.rss / n) + np.log(n) * k) if self.rss > 0 else -np.inf

    def conf_int(self, alpha: float = 0.05) -> pd.DataFrame:
        """Two-sided (1 − alpha) Student-t intervals θ̂ ± t(1−α/2, dof)·σ."""
        if not 0 < alpha < 1:
            raise InputError(f"alpha must be in (0, 1), got {alpha!r}")
        t = stdtrit(self.dof, 1 - alpha / 2)
        # Eq. 4's σ with the samples' degrees of freedom (a subclass's stderr may be another)
        sigma = pd.Series(self.stderr_values, index=self._index)
        return pd.DataFrame({"lower": self.params - t * sigma, "upper": self.params + t * sigma})  # type: ignore[operator]  # pandas-stubs: numpy float × Series is a Series

    # -- the fitted curve, as lmfit's ModelResult gives it --------------------------------
    def eval(self, x: ArrayLike | None = None, **inputs: ArrayLike) -> np.ndarray:
        """The fitted model f(x, θ̂), as lmfit's ``ModelResult.eval``.

        Give the inputs by name — ``fit.eval(z=z)`` for Bernstein, ``fit.eval(b=0.1, z=z)``
        for Bekker and Reece (b [m], z [m]; a scalar broadcasts), ``sigma=`` [Pa] for
        Mohr–Coulomb, ``sigma=, j=`` [Pa, m] for Janosi–Hanamoto, the function's own first
        argument for :func:`~soilstats.identify` on a plain f(x, …) — or positionally as
        the fit took them (the (b, z) rows (2, N) for Bekker). Pressure or stress in Pa.
        """
        if self.model_func is None:
            raise InputError(
                f"this {self.model_name} result carries no model to evaluate (it was built "
                "without one); fit it with soilstats.identify or a fit_* function"
            )
        return np.asarray(self.model_func(self._inputs(x, inputs), *self.values), dtype=float)

    def _inputs(self, x: ArrayLike | None, inputs: dict[str, ArrayLike]) -> Any:
        """The model's ``x`` from a positional ``x`` or the named inputs (checked: a clear
        error for a missing, unknown or 1-D input where the model needs several rows)."""
        names = self.input_names
        how = ", ".join(f"{n}=…" for n in names) if names else "x"
        if inputs:
            if x is not None:
                raise InputError(f"give the inputs of {self.model_name} by name or as x, not both")
            if not names:
                raise InputError(
                    f"this {self.model_name} result does not name its inputs: pass x positionally"
                )
            unknown = sorted(set(inputs) - set(names))
            missing = [n for n in names if n not in inputs]
            if unknown or missing:
                raise InputError(
                    f"{self.model_name} takes the inputs ({', '.join(names)}): "
                    + (f"unknown {unknown}; " if unknown else "")
                    + (f"missing {missing}; " if missing else "")
                    + f"call eval({how})"
                )
            if len(names) == 1:
                return np.asarray(inputs[names[0]], float)
            stacked = np.broadcast_arrays(*(np.asarray(inputs[n], float) for n in names))
            return np.stack([np.atleast_1d(r) for r in stacked])
        if x is None:
            raise InputError(f"{self.model_name}: give the inputs, eval({how})")
        if len(names) > 1:
            # a (b, z) tuple or list of rows, or a (k, N) array: k rows; anything else one
            rows = (
                len(x)
                if isinstance(x, tuple | list)
                else (np.shape(x)[0] if np.ndim(x) == 2 else 1)
            )
            if rows != len(names):
                raise InputError(
                    f"{self.model_name} needs {len(names)} inputs ({', '.join(names)}) but got "
                    f"one array of shape {np.shape(x)}: call eval({how}) (a scalar broadcasts, "
                    f"e.g. eval({names[0]}=0.1, {names[-1]}=...))"
                )
            return x
        return np.asarray(x, float) if isinstance(x, list | tuple) else x

    def eval_uncertainty(
        self, x: ArrayLike | None = None, sigma: float = 1.0, **inputs: ArrayLike
    ) -> np.ndarray:
        """``sigma`` standard deviations of the fitted curve at ``x`` (as :meth:`eval` takes
        it), from the parameter covariance by the delta method: sigma·√diag(J Cov Jᵀ), J the
        model's Jacobian at θ̂ (lmfit's ``ModelResult.eval_uncertainty``). Cov is Eq. 4's
        here; a fit over tests uses the test-level one (:class:`CampaignFit`). Inputs by name
        as for :meth:`eval` (``fit.eval_uncertainty(b=0.1, z=z)``)."""
        return self._band(x, sigma, self.covariance, **inputs)

    def _band(
        self, x: ArrayLike | None, sigma: float, covariance: np.ndarray, **inputs: ArrayLike
    ) -> np.ndarray:
        if self.model_jac is None:
            raise InputError(
                f"this {self.model_name} result carries no model Jacobian; fit it with "
                "soilstats.identify or a fit_* function"
            )
        if not sigma > 0:
            raise InputError(f"sigma must be positive, got {sigma!r}")
        x = self._inputs(x, inputs)
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
            lo, hi = self.bounds.get(name, (-np.inf, np.inf))  # type: ignore[call-overload]  # pandas-stubs: a label is Hashable (ours are str)
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

    # -- the text and notebook views (soilstats.fitting.summary) ----------------------------
    def _summary_parameters(self) -> list[str]:
        """The parameter lines of :meth:`summary`: value, σ (Eq. 3), relative σ, the 95 %
        t-interval and the unit."""
        return parameter_lines(self)

    def summary(self) -> str:
        """A fit report in the manner of lmfit and statsmodels, ending with numbered notes."""
        return fit_summary(self, self._summary_parameters())

    def __str__(self) -> str:
        return self.summary()

    def _parameter_table(self) -> pd.DataFrame:
        """Value, σ (Eq. 3), the 95 % interval and the unit of every parameter."""
        return parameter_frame(self)

    def _repr_html_(self) -> str:
        """The summary as tables, for notebooks."""
        return fit_html(self, self._parameter_table())

    # -- figures, as lmfit's ModelResult.plot_fit / plot_residuals ------------------------
    # ``Any``: matplotlib's Axes, not named here (no analysis module imports matplotlib at all).
    def plot_fit(self, ax: Any = None, *, sigma: float = 2.0, points: int = 200) -> Any:
        """The measured points, the fitted curve and its ±``sigma`` band
        (:meth:`eval_uncertainty`) on ``ax`` (a new figure if None); returns the axes.

        For a model of several inputs (Bekker's (b, z), Janosi's (σ, j)) one curve per value
        of the leading inputs (plate width, normal pressure), against the last input."""
        import matplotlib.pyplot as plt  # deferred: matplotlib (a figure)

        x, y = self._measured("plot_fit")
        ax = ax if ax is not None else plt.subplots()[1]
        for k, (label, mask, lead) in enumerate(self._groups(x)):
            last = x[-1][mask] if x.ndim == 2 else x[mask]
            data_label = "measured" + (f" ({label.strip(', ')})" if label else "")
            line = ax.plot(last, y[mask], "o", ms=3, alpha=0.5, label=data_label)[0]
            grid = np.linspace(np.nanmin(last), np.nanmax(last), points)
            xg = grid if x.ndim == 1 else np.vstack([*(np.full(points, v) for v in lead), grid])
            fit = self.eval(xg)
            fit_label = f"fit ± {sigma:g} σ" if k == 0 else "_nolegend_"
            ax.plot(grid, fit, "-", color=line.get_color(), label=fit_label)
            try:
                band = self.eval_uncertainty(xg, sigma)
            except InputError:
                continue  # no Jacobian: the curve alone
            ax.fill_between(grid, fit - band, fit + band, color=line.get_color(), alpha=0.2)
        self._label_axes(ax, "")
        ax.set_title(f"{self.model_name} fit (band ±{sigma:g} σ)")
        ax.legend(fontsize="small")
        return ax

    def plot_residuals(self, ax: Any = None) -> Any:
        """Measured minus fitted values against the last input, on ``ax`` (a new figure if
        None), one colour per value of the leading inputs; returns the axes."""
        import matplotlib.pyplot as plt  # deferred: matplotlib (a figure)

        x, y = self._measured("plot_residuals")
        ax = ax if ax is not None else plt.subplots()[1]
        resid = y - self.eval(x)
        for label, mask, _ in self._groups(x):
            last = x[-1][mask] if x.ndim == 2 else x[mask]
            ax.plot(last, resid[mask], "o", ms=3, alpha=0.6, label=label.strip(", ") or None)
        ax.axhline(0.0, color="k", lw=0.8)
        self._label_axes(ax, "measured − fitted ")
        ax.set_title(f"{self.model_name}: residuals")
        if x.ndim == 2:
            ax.legend(fontsize="small")
        return ax

    def _measured(self, what: str) -> tuple[np.ndarray, np.ndarray]:
        """The inputs and measurements the fit was made on, for the figure ``what`` (not
        ``_data``: CampaignFit keeps its deferred ``data`` record under that name)."""
        if self.x_data is None or self.y_data is None or self.model_func is None:
            raise InputError(
                f"{what}: this {self.model_name} result carries no data (it was built without "
                "them); fit with soilstats.identify or a fit_* function"
            )
        return np.asarray(self.x_data, float), np.asarray(self.y_data, float)

    def _groups(self, x: np.ndarray) -> list[tuple[str, np.ndarray, tuple[float, ...]]]:
        """(label, mask, leading input values) per distinct value of the leading inputs (all
        points together when there are none, or more than 12 distinct values)."""
        every = np.ones(x.shape[-1], bool)
        if x.ndim == 1 or x.shape[0] < 2:
            return [("", every, ())]
        lead = x[:-1].T
        values = np.unique(lead, axis=0)
        if len(values) > 12:
            return [("", every, tuple(np.median(lead, axis=0)))]
        names = self.input_names[:-1] or tuple(f"x{i}" for i in range(len(lead[0])))
        out = []
        for v in values:
            label = ", " + ", ".join(f"{n} = {u:.4g}" for n, u in zip(names, v, strict=True))
            out.append((label, (lead == v).all(axis=1), tuple(v)))
        return out

    def _label_axes(self, ax: Any, prefix: str) -> None:
        last = self.input_names[-1] if self.input_names else "x"
        ax.set_xlabel(_AXIS_LABELS.get(last, last))
        y = {"z": "pressure p [Pa]", "j": "shear stress τ [Pa]", "sigma": "shear stress τ [Pa]"}
        ax.set_ylabel(prefix + y.get(last, "y"))


_AXIS_LABELS = {
    "z": "sinkage z [m]",
    "j": "shear displacement j [m]",
    "sigma": "normal stress σ [Pa]",
    "b": "plate width b [m]",
}
