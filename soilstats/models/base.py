"""The :class:`Model` record: one soil model and everything a layer needs to know about it.

Its equation with the analytic Jacobian, names, units and bounds (what the optimiser needs),
and its kind, inputs, starting values, default priors, physical support, identifiability
requirements, population layout, simulator mapping and display labels (what identification,
the posteriors, discovery, the studies, the reports and the command line ask of it).  A
model is registered once (:mod:`soilstats.models.registry`) and every layer asks the
registry (docs/conventions.md, "The model record").
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import ClassVar, TypeAlias

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ModelError
from ..kinds import MODEL_KINDS
from .priors import Prior

__all__ = [
    "KINDS",
    "InputRows",
    "Model",
    "NonNegative",
    "ParamLabel",
    "PlatePowerLaw",
    "PopulationLayout",
    "Positive",
    "PositiveModulus",
    "PowerLawPopulation",
    "PowerLawTerms",
    "Value",
    "Within",
    "power_law_population",
    "separable_from_power_law",
]

#: What a soil model describes: a sinkage (plate) test, a shear-ring campaign, or one
#: shear test at one normal pressure (the per-test fit).
KINDS = MODEL_KINDS

#: A parameter or an input of a model equation where it broadcasts: one number, or an array
#: of them (a posterior's draws, a plate size per sample).
Value: TypeAlias = float | np.ndarray
#: The inputs ``x`` of a model with k ≥ 2 inputs: the (k, N) stack, or the k inputs in a
#: sequence (``x = (b, z)``).
InputRows: TypeAlias = np.ndarray | Sequence[Value]


class PowerLawTerms:
    """w·f(x, θ) = Σᵢ aᵢ·w·gᵢ(x)·z^n for fixed inputs x and weights w, θ = (a₁ … a_q, n).

    The form of Bekker (Eq. 7: g = (1/b, 1), a = (kc, kφ)) and Bernstein (Eq. 8: g = 1,
    a = k), with z the sinkage in m: linear in every parameter but the exponent n.  Everything
    that does not depend on θ is computed once here and shared by the optimiser's closures and
    the variable projection of :func:`soilstats.fitting.separable.refine_power_law`, so one
    fit takes ln z once.

    Samples without contact (z ≤ 0) give p = 0 and a zero Jacobian row (z^n has no real value
    there): their weight is folded to zero in ``rows`` and their ln z set to 0.

    Attributes
    ----------
    rows : numpy.ndarray
        (q, N) weighted basis rows Uᵢ = w·gᵢ(x)·[z > 0], so that w·f = (aᵀU)·z^n.
    log_z : numpy.ndarray
        (N,) ln z (0 where z ≤ 0), so that ∂(w·f)/∂n = w·f·ln z.
    """

    __slots__ = ("_block", "_f", "_key", "_n", "_zn", "log_z", "rows")

    log_z: np.ndarray
    rows: np.ndarray
    # The last exponent and θ asked for, and what they gave (None before the first call).
    _n: float | None
    _zn: np.ndarray
    _key: list[float] | None
    _f: np.ndarray
    _block: np.ndarray

    def __init__(self, g: Sequence[Value], z: ArrayLike, w: ArrayLike) -> None:
        z = np.asarray(z, dtype=float)
        w = np.asarray(w, dtype=float)
        # The usual case, one reduction (in C: ndarray.min goes through a Python wrapper);
        # a NaN fails it and is masked below.
        if np.minimum.reduce(z) > 0:
            self.log_z = np.log(z)
        else:
            contact = z > 0
            self.log_z = np.log(np.where(contact, z, 1.0))
            w = np.where(contact, w, 0.0)
        rows = np.empty((len(g), z.size))
        for i, g_i in enumerate(g):
            np.multiply(w, g_i, out=rows[i])
        self.rows = rows
        self._n = self._key = None

    def power(self, n: float) -> np.ndarray:
        """z^n (N,), the last one kept: f, J and the projection ask for the same n in turn."""
        if n != self._n:
            self._zn = np.exp(self.log_z * n)
            self._n = n
        return self._zn

    def basis(self, n: float) -> np.ndarray:
        """U(n) = rows·z^n, (q, N): the weighted basis of the linear parameters."""
        return self.rows * self.power(n)

    def f(self, theta: ArrayLike) -> np.ndarray:
        """w·f(x, θ) = aᵀU(n), (N,) in the units of w·p.

        U(n) is formed in the first rows of the Jacobian's array, which J at the same θ —
        what the optimiser asks for next — then completes with one product.
        """
        theta = np.asarray(theta, dtype=float)
        key = theta.tolist()
        q = len(key) - 1
        block = np.empty((q + 2, self.log_z.size))
        zn = self.power(key[-1])
        for i in range(q):  # row by row: cheaper than numpy's broadcast of zn over q rows
            np.multiply(self.rows[i], zn, out=block[i])
        value = theta[:q] @ block[:q]  # Σ aᵢ·Uᵢ in one BLAS call
        self._key, self._f, self._block = key, value, block
        return value

    def jacobian_block(self, theta: ArrayLike) -> np.ndarray:
        """(q + 2, N): the rows of (w·∂f/∂θ)ᵀ — Uᵢ(n) and w·f·ln z — and a last row that is
        the caller's to overwrite (the optimiser puts the residuals there, so that JᵀJ and
        Jᵀr come from one matrix product; see :func:`~soilstats.fitting.levenberg_marquardt
        .levenberg_marquardt`).  A new array per θ: an earlier J is never overwritten."""
        theta = np.asarray(theta, dtype=float)
        # The optimiser asks for J at the point it has just evaluated: reuse U and w·f.
        if theta.tolist() != self._key:
            self.f(theta)
        block, q = self._block, theta.size - 1
        np.multiply(self._f, self.log_z, out=block[q])
        return block

    def jac(self, theta: ArrayLike) -> np.ndarray:
        """(w·∂f/∂θ)ᵀ, (q + 1, N): rows Uᵢ·z^n and w·f·ln z."""
        theta = np.asarray(theta, dtype=float)
        return self.jacobian_block(theta)[: theta.size]


def separable_from_power_law(
    power_law: Callable, x: ArrayLike, weights: ArrayLike
) -> tuple[Callable, np.ndarray]:
    """``Model.separable`` of a power-law model, from its ``power_law``: (n ↦ U(n), ln z)."""
    g, z = power_law(x)
    terms = PowerLawTerms(g, z, weights)
    return terms.basis, terms.log_z


@dataclass(frozen=True)
class PlatePowerLaw:
    """A plate law that is a power law in the sinkage: p(b, z) = k_eq(b)·z^n.

    ``modulus(b, *params) -> k_eq`` [N/m^(n+2)] at plate width b [m], with ``params`` in the
    record's order and n its ``"n"`` parameter.  As the record's ``plate_pressure`` hook it
    tells the wheel (:mod:`soilstats.wheel`) to take its fast path, σ = k_eq·R^n·(cos θ −
    cos θ1)^n, instead of evaluating the law at every node's depth.  Calling it gives the
    pressure (0 where z ≤ 0), as every ``plate_pressure`` hook does.
    """

    modulus: Callable[..., np.ndarray]
    exponent_index: int = -1  # where n stands among the parameters (last for a power law)

    def __call__(self, b: Value, z: Value, *params: Value) -> np.ndarray:
        z = np.asarray(z, dtype=float)
        n = params[self.exponent_index]
        contact = z > 0
        zn = np.where(contact, np.exp(n * np.log(np.where(contact, z, 1.0))), 0.0)
        return self.modulus(b, *params) * zn


@dataclass(frozen=True)
class _PowerLawModulus:
    """k_eq(b) = Σ aᵢ·gᵢ(b) of a record's ``power_law`` basis (θ = (a₁ … a_q, n)): the
    default plate hook of Bekker and Bernstein.  Module level, so a record pickles."""

    power_law: Callable
    columns: tuple[str, ...]

    def __call__(self, b: Value, *params: Value) -> np.ndarray:
        unit_depth = 1.0
        x = (b, unit_depth) if self.columns == ("b_m", "z_m") else unit_depth
        g, _ = self.power_law(x)
        return sum((a * g_i for a, g_i in zip(params[:-1], g, strict=True)), np.asarray(0.0))


@dataclass(frozen=True)
class _FuncPlatePressure:
    """p(b, z) from a sinkage record's own ``func`` on x = (b, z) or z (its ``columns``)."""

    func: Callable
    columns: tuple[str, ...]

    def __call__(self, b: Value, z: Value, *params: Value) -> np.ndarray:
        b, z = np.broadcast_arrays(np.asarray(b, float), np.asarray(z, float))
        x = (b, z) if self.columns == ("b_m", "z_m") else z
        return np.asarray(self.func(x, *params), dtype=float)


# ------------------------------------------------------------------- parts of the record
@dataclass(frozen=True)
class _ParameterRule:
    """Support rule on one parameter: a draw breaking it is counted as ``label``."""

    name: str
    broken: ClassVar[str] = ""

    @property
    def params(self) -> tuple[str, ...]:
        return (self.name,)

    @property
    def label(self) -> str:
        return f"{self.name} {self.broken}"

    def holds(self, values: Mapping[str, np.ndarray], widths: tuple[float, float]) -> np.ndarray:
        return self._inside(values[self.name])

    def _inside(self, x: np.ndarray) -> np.ndarray:  # pragma: no cover (abstract)
        raise NotImplementedError


@dataclass(frozen=True)
class Positive(_ParameterRule):
    """Support rule: ``name`` > 0 (broken: ``"{name} <= 0"``)."""

    broken: ClassVar[str] = "<= 0"

    def _inside(self, x):
        return x > 0


@dataclass(frozen=True)
class NonNegative(_ParameterRule):
    """Support rule: ``name`` ≥ 0 (c of a cohesionless sand is 0)."""

    broken: ClassVar[str] = "< 0"

    def _inside(self, x):
        return x >= 0


@dataclass(frozen=True)
class Within(_ParameterRule):
    """Support rule: ``lower`` < ``name`` < ``upper`` (in ``unit``)."""

    lower: float = -np.inf
    upper: float = np.inf
    unit: str = ""

    @property
    def label(self) -> str:
        return f"{self.name} outside ({self.lower:g}, {self.upper:g}) {self.unit}".rstrip()

    def _inside(self, x):
        return (x > self.lower) & (x < self.upper)


@dataclass(frozen=True)
class PositiveModulus:
    """Support rule and prior constraint: the plate modulus ``modulus(b, *params)`` (the
    pressure at unit sinkage on a plate of width b, e.g. Bekker's kc/b + kφ) is positive at
    every plate width used.  It is monotone in b, so the smallest and largest width decide.

    ``text`` names it in messages (``"kc/b + kphi"``); ``params`` are the model's parameter
    names, in the order ``modulus`` takes them after b.
    """

    text: str
    modulus: Callable[..., np.ndarray]
    params: tuple[str, ...]

    @property
    def label(self) -> str:
        return f"{self.text} <= 0"

    def holds(self, values: Mapping[str, np.ndarray], widths: tuple[float, float]) -> np.ndarray:
        lo, hi = widths
        args = [values[n] for n in self.params]
        return (self.modulus(lo, *args) > 0) & (self.modulus(hi, *args) > 0)


@dataclass(frozen=True)
class ParamLabel:
    """How reports show a parameter: ``symbol`` in Typst math (``k_phi``); for figures the
    matplotlib ``axis`` label, the ``caption`` name, the display ``unit`` (mathtext) and
    its ``unit_words``, and the ``scale`` from the SI value to the displayed one."""

    symbol: str
    axis: str | None = None
    caption: str | None = None
    unit: str | None = None
    unit_words: str | None = None
    scale: float = 1.0


@dataclass(frozen=True)
class PopulationLayout:
    """How a soil model maps onto the population (hierarchical) posterior
    (:mod:`soilstats.bayes.population_model`, module docstring): a subclass per family of
    models states the maps.

    ``linear(θ)`` → the moduli m that enter a test's first per-test parameter linearly
    (a_tᵀm); ``second(θ)`` → g, the soil-level value of the second per-test coordinate;
    ``assemble(m, g)`` → θ back; ``linear_log_jacobian(θ)`` → log dθ_linear/d(moduli).
    ``log_second``: the per-test fit's second parameter enters η as its logarithm (K)
    rather than as it is (n).
    """

    per_test: tuple[str, str]  # names of the per-test fit's two parameters
    scatter: tuple[str, str, str]  # names of s_ε, s_δ, ρ in the posterior
    covariate: str  # per-test quantity of the design row: b_m or sigma_Pa
    log_second: bool
    scatter_note: str

    def linear_log_jacobian(self, theta: np.ndarray) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def linear(self, theta: np.ndarray) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def second(self, theta: np.ndarray) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def assemble(self, m: np.ndarray, g: np.ndarray) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError


@dataclass(frozen=True)
class PowerLawPopulation(PopulationLayout):
    """A power law θ = (a₁ … a_q, n): each test a Bernstein fit (k_t, n_t) whose k_t is
    linear in the moduli a (``Model.power_law``'s basis at its b); the moduli are the
    parameters themselves, so their log-Jacobian is 0."""

    def linear_log_jacobian(self, theta: np.ndarray) -> np.ndarray:
        return np.zeros(theta.shape[0])

    def linear(self, theta: np.ndarray) -> np.ndarray:
        return theta[:, :-1]

    def second(self, theta: np.ndarray) -> np.ndarray:
        return theta[:, -1]

    def assemble(self, m: np.ndarray, g: np.ndarray) -> np.ndarray:
        return np.column_stack([m, g])


def power_law_population(scatter_note: str) -> PowerLawPopulation:
    """The population layout of a power-law sinkage model (:class:`PowerLawPopulation`)."""
    scatter = ("sd_p_ref", "sd_n", "corr_p_ref_n")
    return PowerLawPopulation(("k", "n"), scatter, "b_m", False, scatter_note)


def _pairs(value: Mapping | tuple) -> tuple:
    """A mapping as a tuple of its items (the record stays hashable); a tuple as it is."""
    return tuple(value.items()) if isinstance(value, Mapping) else tuple(value)


@dataclass(frozen=True)
class Model:
    """A soil model y = f(x, θ): the one record every layer asks about it.

    The first block of attributes is what the optimiser needs (any ``Model`` has them; the
    extended families of discovery build such models on the fly).  The second is what the
    layers above ask of a *soil* model — registered by name
    (:func:`~soilstats.models.registry.register_model`), so that identification, the
    posteriors, discovery, the studies, the reports and the command line keep no list of
    models of their own.  Each has a default that means "not applicable".

    Attributes
    ----------
    name : str
        Short name used throughout (``"bekker"``, ``"janosi"`` …).
    equation : str
        Where the equation stands in the paper (e.g. ``"Eq. 7"``) and its formula.
    inputs : tuple of str
        Meaning and unit of each row of ``x`` (``x`` is 1-D for one input, shape (k, N) for k).
    param_names, units : tuple of str
        Parameter names (``params`` are indexed by them) and SI units.
    bounds : tuple of (low, high)
        Physically plausible range of each parameter.  Fits are *not* constrained to it
        (a constrained optimum has no valid covariance); a value outside is a health flag.
    func : callable
        ``func(x, *params) -> y`` vectorised over samples.
    jac : callable
        ``jac(x, *params) -> (N, p)`` analytic ∂f/∂θ.
    prepare : callable, optional
        ``prepare(x, w) -> (θ ↦ w·f, θ ↦ (w·∂f/∂θ)ᵀ)``: closures over ``x`` and the weights
        ``w`` (N,) that precompute what does not depend on θ (e.g. ln z, w/b), share work
        between f and its Jacobian, and return the Jacobian as (p, N) rows.  Same values as
        ``func``/``jac``; used by the optimiser where speed matters.
    separable : callable, optional
        For models linear in all parameters but a last exponent n (p = Σ aᵢ·gᵢ(x)·z^n):
        ``separable(x, w) -> (n ↦ U(n), ln z)`` with U the (q, N) weighted basis rows
        w·gᵢ(x)·z^n.  Lets the identification reach the optimum by variable projection
        before its LM (see :mod:`soilstats.fitting.separable`); for a power-law model,
        :func:`separable_from_power_law` (the batched bootstrap uses it).
    power_law : callable, optional
        For the same models, ``power_law(x) -> (g, z)``: the q basis functions gᵢ(x) (arrays
        of shape (N,) or scalars) and the sinkage z (N,).  Gives :class:`PowerLawTerms`, from
        which the identification takes its closures and its variable projection (one ln z
        per fit, the projection in scalar arithmetic on precomputed moments).
    linear_form : callable, optional
        For models linear in their parameters after a change of variables (Mohr–Coulomb:
        c and tan φ): ``linear_form(x) -> (X, to_params)`` with the (N, p) design X and
        ``to_params`` mapping (B, p) coefficients of X to (B, p) model parameters.  The
        bootstrap then solves every resample in closed form, as the fit itself is solved.
    kind : {"sinkage", "shear", "shear-test"}
        The tests it describes (:data:`KINDS`): plate-sinkage tests, the shear-ring tests of
        a campaign, or one shear test at one normal pressure (the per-test fit).  Empty for
        a model that is no soil model (an extended family, a NIST test problem).
    columns : tuple of str
        The pooled-data columns that make ``x``, in the order of ``inputs`` (``("b_m",
        "z_m")`` for Bekker; :meth:`x_from` builds ``x`` from them).
    start : callable, optional
        ``start(x, y) -> θ₀``: the starting values of the LM identification, a cheap
        closed-form estimate (:mod:`soilstats.models.starting_values`).
    wong : callable, optional
        ``wong(x, y) -> (θ, cov, n_excluded)``: Wong's linearised method (Fig. 3), where the
        model has one (Bekker, Bernstein).
    priors : mapping or tuple of (name, Prior)
        Default prior of each parameter of the posteriors (:mod:`soilstats.models.priors`);
        a parameter without one is flat on ℝ.  Stored as (name, Prior) pairs.
    support : tuple of rules
        The physical support of a parameter draw (:class:`Positive`, :class:`NonNegative`,
        :class:`Within`, :class:`PositiveModulus`), checked in this order; a
        :class:`PositiveModulus` rule also constrains the pooled posterior's prior at the
        plate sizes of the data.
    min_plate_sizes : int, default 1
        Plate sizes b the tests of one fit must span (2 where kc/b and kφ, or k1 and k2·b,
        are told apart only by the spread of b; Section 2.1).
    design_input : str, optional
        The pooled input whose spread separates the parameters (``"b_m"``, ``"sigma_Pa"``):
        a bootstrap resample that spans too little of it counts as failed.
    steady_state : bool, default False
        Identified from the steady-state part of each shear test (Mohr–Coulomb, Eq. 15),
        not from whole records.
    weighting : str, optional
        The default weighting of the pooled fit (``"max-pressure"``, ``"max-stress"``,
        ``"none"``; Section 2.1).
    population : PopulationLayout, optional
        How the model maps onto the population posterior; None: pooled posterior only.
    scm : mapping or tuple of (name, (column, unit))
        The Chrono SCM soil parameter each parameter is, with the SCM unit
        (:mod:`soilstats.bayes.export`); empty where SCM has none.
    labels : mapping or tuple of (name, ParamLabel)
        How reports show each parameter; a parameter without one is shown by its name.
    plate_pressure : callable, optional
        The one hook the wheel (:mod:`soilstats.wheel`) asks: ``plate_pressure(b, z,
        *params) -> p`` [Pa], the pressure under a plate of width b [m] at sinkage z [m],
        vectorised (b, z and the parameters broadcast; 0 where z ≤ 0).  A
        :class:`PlatePowerLaw` (p = k_eq(b)·z^n) gives the wheel its power-law fast path.
        Default (:meth:`plate_law`): for a power law (``power_law``), k_eq(b)·z^n from its
        basis; else the record's ``func`` where its columns are (b, z) or z.
    signed : tuple of str
        Parameters whose sign is a physical statement (a modulus that may take either
        sign): the test bootstrap flags an unstable sign.
    """

    name: str
    equation: str
    inputs: tuple[str, ...]
    output: str
    param_names: tuple[str, ...]
    units: tuple[str, ...]
    bounds: tuple[tuple[float, float], ...]
    func: Callable[..., np.ndarray] = field(repr=False)
    jac: Callable[..., np.ndarray] = field(repr=False)
    prepare: Callable | None = field(default=None, repr=False)
    separable: Callable | None = field(default=None, repr=False)
    power_law: Callable | None = field(default=None, repr=False)
    linear_form: Callable | None = field(default=None, repr=False)
    kind: str = ""
    columns: tuple[str, ...] = ()
    start: Callable | None = field(default=None, repr=False)
    wong: Callable | None = field(default=None, repr=False)
    # priors, scm, labels: a mapping or (name, value) pairs; pairs after __post_init__.
    priors: tuple[tuple[str, Prior], ...] | Mapping[str, Prior] = field(default=(), repr=False)
    support: tuple = field(default=(), repr=False)
    min_plate_sizes: int = 1
    design_input: str | None = None
    steady_state: bool = False
    weighting: str | None = None
    population: PopulationLayout | None = field(default=None, repr=False)
    scm: tuple[tuple[str, tuple[str, str]], ...] | Mapping[str, tuple[str, str]] = field(
        default=(), repr=False
    )
    labels: tuple[tuple[str, ParamLabel], ...] | Mapping[str, ParamLabel] = field(
        default=(), repr=False
    )
    signed: tuple[str, ...] = ()
    plate_pressure: Callable | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        for name in ("priors", "scm", "labels"):
            object.__setattr__(self, name, _pairs(getattr(self, name)))
        if self.kind and self.kind not in KINDS:
            raise ModelError(f"model {self.name!r}: kind must be one of {KINDS}, got {self.kind!r}")
        if self.columns and len(self.columns) != len(self.inputs):
            raise ModelError(
                f"model {self.name!r}: columns {self.columns} do not match inputs {self.inputs}"
            )
        unknown = {n for n, _ in (*self.priors, *self.scm, *self.labels)} - set(self.param_names)
        if unknown:
            raise ModelError(
                f"model {self.name!r}: priors, scm or labels name {sorted(unknown)}, which are "
                f"not parameters (parameters: {list(self.param_names)})"
            )

    def power_terms(self, x: ArrayLike, weights: ArrayLike) -> PowerLawTerms | None:
        """:class:`PowerLawTerms` of a power-law model for ``x`` and weights, else None."""
        if self.power_law is None:
            return None
        g, z = self.power_law(x)
        return PowerLawTerms(g, z, weights)

    def evaluators(self, x: ArrayLike, weights: ArrayLike) -> tuple[Callable, Callable]:
        """(θ ↦ w·f(x, θ), θ ↦ (w·∂f/∂θ)ᵀ of shape (p, N)) for fixed ``x`` and weights ``w``.

        The model's fast closures where it has them (see ``prepare`` and ``power_law``), else
        wrappers of ``func`` and ``jac``.
        """
        w = np.asarray(weights, dtype=float)
        if self.prepare is not None:
            return self.prepare(x, w)
        if self.power_law is not None:
            g, z = self.power_law(x)
            terms = PowerLawTerms(g, z, w)
            return terms.f, terms.jac
        w_col = w[:, None]

        def f_weighted(theta):
            return w * np.asarray(self.func(x, *theta), float)

        def jac_rows(theta):
            return (w_col * np.asarray(self.jac(x, *theta), float)).T

        return f_weighted, jac_rows

    def __call__(self, x: ArrayLike, *params: Value) -> np.ndarray:
        return self.func(x, *params)

    def plate_law(self) -> Callable[..., np.ndarray] | None:
        """The plate hook ``(b, z, *params) -> p`` [Pa] (``plate_pressure``), or its default:
        a :class:`PlatePowerLaw` from ``power_law`` for a power law, else ``func`` on (b, z)
        or z; None for a record whose inputs are not a plate's (b, z)."""
        if self.plate_pressure is not None:
            return self.plate_pressure
        if self.kind != "sinkage" or self.columns not in (("b_m", "z_m"), ("z_m",)):
            return None
        if self.power_law is not None and self.exponent == self.param_names[-1]:
            return PlatePowerLaw(_PowerLawModulus(self.power_law, self.columns))
        return _FuncPlatePressure(self.func, self.columns)

    def pressure_under_plate(self, b: Value, z: Value, *params: Value) -> np.ndarray:
        """p [Pa] under a plate of width b [m] at sinkage z [m] (:meth:`plate_law`)."""
        law = self.plate_law()
        if law is None:
            raise ModelError(
                f"model {self.name!r} gives no pressure under a plate (its inputs are "
                f"{self.columns}): state Model.plate_pressure(b, z, *params)"
            )
        return np.asarray(law(b, z, *params), dtype=float)

    def plate_modulus(self, b: Value, *params: Value) -> np.ndarray | None:
        """k_eq(b) [N/m^(n+2)] of a plate law that is a power law (p = k_eq·z^n), else None:
        the wheel's fast path."""
        law = self.plate_law()
        if not isinstance(law, PlatePowerLaw):
            return None
        return np.asarray(law.modulus(b, *params), dtype=float)

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    @property
    def unit_of(self) -> dict[str, str]:
        """SI unit of each parameter, by name."""
        return dict(zip(self.param_names, self.units, strict=True))

    @property
    def bounds_of(self) -> dict[str, tuple[float, float]]:
        """Physically plausible range of each parameter, by name."""
        return dict(zip(self.param_names, self.bounds, strict=True))

    @property
    def prior_of(self) -> dict:
        """Default prior of each parameter that has one, by name."""
        return dict(self.priors)

    @property
    def label_of(self) -> dict[str, ParamLabel]:
        """Display label of each parameter that has one, by name."""
        return dict(self.labels)

    @property
    def scm_of(self) -> dict[str, tuple[str, str]]:
        """Chrono SCM (column, unit) of each parameter SCM takes, by name."""
        return dict(self.scm)

    @property
    def modulus(self) -> PositiveModulus | None:
        """The plate-modulus rule of the support, if the model has one."""
        return next((r for r in self.support if isinstance(r, PositiveModulus)), None)

    @property
    def exponent(self) -> str | None:
        """The sinkage exponent's name (``"n"``), if the model has one: the parameter a
        shape effect offsets (discovery)."""
        return "n" if "n" in self.param_names else None

    def x_from(self, data: Mapping[str, np.ndarray]) -> np.ndarray:
        """``x`` from the pooled data's columns (:attr:`columns`): the one array of a model
        with one input, else the (k, N) stack."""
        if not self.columns:
            raise ModelError(f"model {self.name!r} states no data columns (Model.columns)")
        cols = [data[c] for c in self.columns]
        return cols[0] if len(cols) == 1 else np.vstack(cols)
