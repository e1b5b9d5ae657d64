"""The extended models that discovery may propose, and the base models they extend (which
of them it proposes for a cause: :mod:`soilstats.discovery.library`).

Physically motivated (each named by the paper's Sections 3–4):

``velocity``     k·(v/v_ref)^a and n + m·ln(v/v_ref): fine soils stiffen at low penetration
                 velocity (Section 3.1.2, Table 5).
``softening``    beyond a critical sinkage z_c, plates with aspect ratio ≥ a threshold soften:
                 p = p(z_c) + f·(p − p(z_c)) (Section 3.1.3, Figs. 8–9); the threshold is
                 chosen from the training data's aspect ratios.
``reece``        Reece's size dependence p = (k1 + k2·b)(z/b)^n in place of Bekker's Eq. 7.
``side-walls``   the ring's cylindrical walls carry shear too (Section 4.2.3): apparent
                 c·(1 + a) and tan φ·(1 + a·K0), a = 3h(r_i² + r_o²)/(r_o³ − r_i³).

Generic, for covariates no physics names: a parameter that depends on the covariate —
``levels`` (one factor per level of a categorical covariate) or ``linear`` (a log-linear
trend in a numeric one, on ln x where x spans more than a factor four, except for a
time/order cause: a drift is linear in time).  Stiffness-type
parameters (k or kc, kφ; c, tan φ, K) change by a factor exp(θ·F); the exponent n by an
offset.

Every extension fits on a set of tests (``rows`` of a :class:`Group`) and predicts the curves
of other tests, so that cross-validation can measure it out of sample.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, cast

import numpy as np

from ..errors import ConvergenceError, IdentifiabilityError, ModelError
from ..fitting.identify import identify
from ..fitting.result import FitResult
from ..models import BEKKER, BERNSTEIN, JANOSI, REECE, Model, side_wall_ratio
from ..models.extended import (
    ShearFamily,
    ShearLayout,
    SinkageFamily,
    SinkageLayout,
    model_family,
    shear_family,
    sinkage_family,
)
from ..models.starting_values import janosi_start, reece_from_bekker, sinkage_start
from ..models.wong import wong_start
from .candidates import MISSING, spans_log
from .separable import check_shear_terms, sinkage_keeps_bekker

if TYPE_CHECKING:
    from .data import Group

__all__ = [
    "Extension",
    "Features",
    "FitStart",
    "Fitted",
    "ModelExtension",
    "ReeceExtension",
    "ShearExtension",
    "SinkageExtension",
    "Term",
    "check_own_model",
    "shear_inputs_a",
]

#: Physically plausible ranges (health flags of the fit, not constraints of the optimiser):
#: those of the base models; extension parameters are unbounded unless stated.
_SINK_UNITS = {**BEKKER.unit_of, **BERNSTEIN.unit_of}
_SINK_BOUNDS = {**BEKKER.bounds_of, **BERNSTEIN.bounds_of}


@dataclass(frozen=True)
class Features:
    """How a covariate becomes per-test features: ``velocity``, ``linear``, ``levels`` or
    ``block-linear`` (a linear trend in ``column`` of its own in each block named by the
    labels of column ``by``: a drift inside one block of the design)."""

    column: str
    how: str  # "velocity" | "linear" | "levels" | "block-linear"
    log_scale: bool = True  # "linear" may use ln x (not for time/order: a drift)
    by: str | None = None  # "block-linear": the column of block labels

    def prepare(self, group: Group, rows: np.ndarray) -> dict:
        """Reference values from the training tests only (no peeking at held-out tests)."""
        values = group.values(self.column).iloc[rows]
        if self.how == "block-linear":
            by = cast(str, self.by)  # a block-linear trend names its blocks' column
            blocks = group.values(by).iloc[rows].astype(object).fillna(MISSING)
            numbers = values.astype(float)
            state: dict[str, list] = {"blocks": [], "mean": [], "sd": []}
            for lv in dict.fromkeys(blocks):
                xb = numbers[(blocks == lv).to_numpy()].dropna().to_numpy()
                if xb.size >= 2 and np.ptp(xb) > 0:
                    state["blocks"].append(lv)
                    state["mean"].append(float(xb.mean()))
                    state["sd"].append(float(xb.std()))
            return state
        if self.how == "levels":
            counts = values.astype(object).fillna(MISSING).value_counts(sort=False)
            levels = list(counts.index)
            reference = counts.idxmax()  # most tests: the best-determined baseline
            return {"levels": [lv for lv in levels if lv != reference], "reference": reference}
        x = values.astype(float).to_numpy()
        x = x[np.isfinite(x)]
        if self.how == "velocity":
            return {"v_ref": float(np.exp(np.mean(np.log(x))))}
        use_log = self.log_scale and spans_log(x)
        g = np.log(x) if use_log else x
        return {"log": use_log, "mean": float(g.mean()), "sd": float(g.std()) or 1.0}

    def names(self, state: dict) -> list[str]:
        if self.how == "block-linear":
            return [f"{self.column} drift in {lv}" for lv in state["blocks"]]
        if self.how == "levels":
            return [f"{self.column}={lv}" for lv in state["levels"]]
        if self.how == "velocity":
            return ["ln(v/v_ref)"]
        return [f"{'ln ' if state['log'] else ''}{self.column} (standardised)"]

    def matrix(self, group: Group, state: dict) -> np.ndarray:
        """(n_tests, m) features of every test of the group (unseen levels → reference)."""
        if self.how == "block-linear":
            x = group.memo(
                ("float", self.column), lambda: group.values(self.column).astype(float).to_numpy()
            )
            by = cast(str, self.by)  # a block-linear trend names its blocks' column
            blocks = group.memo(
                ("levels", by),
                lambda: group.values(by).astype(object).fillna(MISSING).to_numpy(),
            )
            cols = [
                np.where(blocks == lv, (x - m) / sd, 0.0)
                for lv, m, sd in zip(state["blocks"], state["mean"], state["sd"], strict=True)
            ]
            out = np.column_stack(cols) if cols else np.zeros((x.size, 0))
            return np.nan_to_num(out, nan=0.0, posinf=0.0, neginf=0.0)
        if self.how == "levels":
            v = group.memo(
                ("levels", self.column),
                lambda: group.values(self.column).astype(object).fillna(MISSING).to_numpy(),
            )
            return np.column_stack([v == lv for lv in state["levels"]]).astype(float)
        x = group.memo(
            ("float", self.column), lambda: group.values(self.column).astype(float).to_numpy()
        )
        if self.how == "velocity":
            with np.errstate(divide="ignore", invalid="ignore"):
                out = np.log(x / state["v_ref"])
        else:
            with np.errstate(divide="ignore", invalid="ignore"):
                g = np.log(x) if state["log"] else x
            out = (g - state["mean"]) / state["sd"]
        return np.nan_to_num(out, nan=0.0, posinf=0.0, neginf=0.0)[:, None]


@dataclass(frozen=True)
class Term:
    """One covariate effect of an extended model: the features and the parameters they move.

    ``targets``: sinkage ``"k"`` (stiffness factor exp(θ·F)) and/or ``"n"`` (exponent offset
    θ·F); shear any of ``"c"``, ``"tan_phi"``, ``"K"`` (factors exp(θ·F)).  Terms of several
    causes add up in one model (:func:`soilstats.discovery.library.combine`).
    """

    features: Features
    targets: tuple[str, ...]

    @property
    def cause(self) -> str:
        return self.features.column


def _prepare_terms(terms: Sequence[Term], group: Group, rows: np.ndarray) -> list[dict]:
    return [t.features.prepare(group, rows) for t in terms]


def _stack(
    terms: Sequence[Term], states: Sequence[dict], group: Group, owner: np.ndarray, target: str
) -> np.ndarray | None:
    """Per-sample features of every term that moves ``target``, side by side (or None).

    Built as contiguous (m, N) rows, the layout of the family's Jacobian rows, and handed
    over as their (N, m) transpose (which the family takes without a copy)."""
    blocks = [
        t.features.matrix(group, st).T[:, owner]
        for t, st in zip(terms, states, strict=True)
        if target in t.targets
    ]
    return np.vstack(blocks).T if blocks else None


def _term_names(
    terms: Sequence[Term], states: Sequence[dict], target: str, label: str
) -> list[str]:
    return [
        label.format(n)
        for t, st in zip(terms, states, strict=True)
        if target in t.targets
        for n in t.features.names(st)
    ]


def _sinkage_features(terms, group, rows, state):
    """``(mask, owner, fs, gd)``: the samples of the tests ``rows``, their tests, and the
    per-sample features of the stiffness (``"k"``) and exponent (``"n"``) terms."""
    mask = group.samples_of(rows)
    owner = group.owner[mask]
    states = state.get("terms", [])
    fs = _stack(terms, states, group, owner, "k")
    gd = _stack(terms, states, group, owner, "n")
    return mask, owner, fs, gd


def _add_term_names(names: list, units: list, terms: Sequence[Term], state: dict) -> None:
    """Append the names (and unit "-") of the stiffness factors and exponent offsets."""
    states = state.get("terms", [])
    for target, label in (("k", "ln k-factor[{}]"), ("n", "n-offset[{}]")):
        extra = _term_names(terms, states, target, label)
        names += extra
        units += ["-"] * len(extra)


@dataclass(frozen=True, eq=False)
class Fitted:
    """An extension fitted on some tests: the identification result and its fitted state."""

    extension: Extension
    result: FitResult
    state: dict = field(default_factory=dict)


class FitValues(Protocol):
    """The parameter values of a fit (``FitResult.values``)."""

    @property
    def values(self) -> np.ndarray: ...


class FitStart(Protocol):
    """What a fit starts from (``Extension.fit``'s ``base``): a :class:`Fitted`, or a fold
    fit's :class:`~.work.Start` as it comes back from a worker — the extension, its
    parameter values (``result.values``) and the base form its fit chose (``state``)."""

    @property
    def extension(self) -> Extension: ...

    @property
    def result(self) -> FitValues: ...

    @property
    def state(self) -> dict: ...


def _uses_bekker(fitted: FitStart) -> bool | None:
    """Whether a fitted sinkage model kept Eq. 7 (None for Reece and shear models)."""
    return fitted.state.get("bekker", getattr(fitted.extension, "bekker", None))


@dataclass(frozen=True)
class Extension:
    """Base of every model in the library (including the base models themselves)."""

    name: str
    physical: bool
    description: str

    def fit(
        self, group: Group, rows: np.ndarray, base: FitStart | None = None
    ) -> Fitted:  # pragma: no cover
        raise NotImplementedError

    def predict(
        self, fitted: Fitted, group: Group, rows: np.ndarray
    ) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError


def _identify(
    family: SinkageFamily | ShearFamily,
    y: np.ndarray,
    w: np.ndarray,
    p0: Sequence[float],
    names: list[str],
    units: list[str],
    bounds: dict[str, tuple[float, float]],
    label: str,
) -> FitResult:
    """Weighted LM (Eq. 1) of an extended family, through its :class:`Model` so that
    :func:`identify` takes the fast path (weights folded in, f and J sharing their parts)."""
    return identify(
        family.model(names, units, bounds, label),
        np.arange(y.size),
        y,
        p0,
        weights=w,
        param_names=names,
        units=dict(zip(names, units, strict=True)),
        bounds=bounds,
        name=label,
    )


# --------------------------------------------------------------------------- sinkage models
@dataclass(frozen=True)
class SinkageExtension(Extension):
    """Bekker (Eq. 7) or Bernstein (Eq. 8) with covariate terms and/or softening."""

    bekker: bool = True
    terms: tuple[Term, ...] = ()
    soften: bool = False

    def _inputs(self, group, rows, state):
        mask, owner, fs, gd = _sinkage_features(self.terms, group, rows, state)
        soft = None
        if self.soften:
            aspect = group.tests["aspect_ratio"].to_numpy(float)[owner]
            soft = aspect >= state["min_aspect"] - 1e-9
        n_s = 0 if fs is None else fs.shape[1]
        n_d = 0 if gd is None else gd.shape[1]
        layout = SinkageLayout(state.get("bekker", self.bekker), n_s, n_d, self.soften)
        return (
            mask,
            layout,
            sinkage_family(layout, group.x["b"][mask], group.x["z"][mask], fs, gd, soft),
        )

    def _names(self, state):
        names = ["kc", "kphi", "n"] if state.get("bekker", self.bekker) else ["k", "n"]
        units = [_SINK_UNITS[n] for n in names]
        _add_term_names(names, units, self.terms, state)
        if self.soften:
            names += ["z_c", "f_soft"]
            units += ["m", "-"]
        return names, units

    def fit(self, group: Group, rows: np.ndarray, base: FitStart | None = None) -> Fitted:
        rows = np.asarray(rows, int)
        state: dict = {"terms": _prepare_terms(self.terms, group, rows)}
        bekker = sinkage_keeps_bekker(
            self.name, self.bekker, self.terms, state["terms"], group, rows
        )
        if bekker != self.bekker:
            state["bekker"] = bekker
        mask = group.samples_of(rows)
        y, w = group.y[mask], group.w[mask]
        if base is not None and _uses_bekker(base) == bekker:
            start = list(base.result.values[: 3 if bekker else 2])
        else:
            model = "bekker" if bekker else "bernstein"
            start = list(sinkage_start(model, group.x["b"][mask], group.x["z"][mask], y))
        if not self.soften:
            mask, layout, family = self._inputs(group, rows, state)
            p0 = start + [0.0] * (layout.size - len(start))
            names, units = self._names(state)
            result = _identify(family, y, w, p0, names, units, _SINK_BOUNDS, self.name)
            return Fitted(self, result, state)
        return self._fit_softening(group, rows, state, start)

    def _fit_softening(
        self, group: Group, rows: np.ndarray, state: dict, start: list[float]
    ) -> Fitted:
        aspect = group.tests["aspect_ratio"].to_numpy(float)[rows]
        thresholds = sorted({a for a in np.round(aspect, 6) if a >= 1.5})
        if not thresholds:
            raise IdentifiabilityError(
                f"{self.name}: no plate with aspect ratio ≥ 1.5 among the training tests; the "
                "softening of narrow plates (Fig. 9) cannot be fitted"
            )
        best, errors = None, []
        # z_c start: the best of a few depths, with the paper's "softer" factor 0.6.
        grid = np.quantile(group.x["z"][group.samples_of(rows)], [0.1, 0.2, 0.35, 0.5, 0.7])
        bounds = {**_SINK_BOUNDS, "z_c": (0, np.inf), "f_soft": (0, 1)}
        for thr in thresholds:
            st = {**state, "min_aspect": float(thr)}
            mask, layout, family = self._inputs(group, rows, st)
            y, w = group.y[mask], group.w[mask]
            names, units = self._names(st)
            base_p0 = start + [0.0] * (layout.size - 2 - len(start))
            rss = [np.sum((w * (y - family.f(np.array([*base_p0, zc, 0.6])))) ** 2) for zc in grid]
            p0 = [*base_p0, float(grid[int(np.argmin(rss))]), 0.6]
            try:
                result = _identify(family, y, w, p0, names, units, bounds, self.name)
            except ConvergenceError as exc:
                errors.append(f"aspect ≥ {thr:g}: {exc}")
                continue
            if best is None or result.rss < best.result.rss:
                best = Fitted(self, result, st)
        if best is None:
            raise ConvergenceError(f"{self.name}: no threshold converged — " + "; ".join(errors))
        return best

    def predict(self, fitted: Fitted, group: Group, rows: np.ndarray) -> np.ndarray:
        _, _, family = self._inputs(group, np.asarray(rows, int), fitted.state)
        return family.f(fitted.result.values)


@dataclass(frozen=True)
class ReeceExtension(Extension):
    """Reece's p = (k1 + k2·b)(z/b)^n: the plate size enters through z/b, not kc/b."""

    def fit(self, group: Group, rows: np.ndarray, base: FitStart | None = None) -> Fitted:
        mask = group.samples_of(np.asarray(rows, int))
        b, z, y, w = group.x["b"][mask], group.x["z"][mask], group.y[mask], group.w[mask]
        theta = base.result.values if base is not None else wong_start(b, z, y)
        p0 = reece_from_bekker(theta, b)
        result = identify(REECE, np.vstack([b, z]), y, p0, weights=w, name=self.name)
        return Fitted(self, result, {})

    def predict(self, fitted: Fitted, group: Group, rows: np.ndarray) -> np.ndarray:
        mask = group.samples_of(np.asarray(rows, int))
        return REECE.func(
            np.vstack([group.x["b"][mask], group.x["z"][mask]]), *fitted.result.values
        )


# ------------------------------------------------------------- a registered model of one's own
#: A group's per-sample inputs (:class:`~.data.Group`) by the pooled-data column a model
#: record names (``Model.columns``), per kind.
_GROUP_INPUTS = {"sinkage": {"b_m": "b", "z_m": "z"}, "shear": {"sigma_Pa": "sigma", "j_m": "j"}}


def check_own_model(model: Model) -> None:
    """Raise :class:`~soilstats.errors.ModelError` unless discovery has every input the
    registered ``model`` takes (``Model.columns``) and its starting values."""
    have = _GROUP_INPUTS.get(model.kind, {})
    missing = [c for c in model.columns if c not in have]
    if missing or model.start is None:
        raise ModelError(
            f"discovery cannot fit {model.name!r}: "
            + (
                f"it takes {missing}, and discovery has the inputs {sorted(have)}"
                if missing
                else "its record states no starting values (Model.start)"
            )
        )


@dataclass(frozen=True)
class ModelExtension(Extension):
    """A registered model (``discover(model=...)``, docs/conventions.md "The model record")
    with covariate terms: a factor exp(θ·F) on its output for ``"k"`` (stiffness) targets
    and an offset θ·F on its exponent n for ``"n"`` targets (:class:`~soilstats.models
    .extended.ModelFamily`).  It starts from the record's starting values."""

    model: Model = field(kw_only=True)  # the Model record
    terms: tuple[Term, ...] = ()

    def _x(self, group, mask):
        names = _GROUP_INPUTS[self.model.kind]
        data = {c: group.x[names[c]][mask] for c in self.model.columns}
        return self.model.x_from(data)

    def _inputs(self, group, rows, state):
        mask, _, fs, gd = _sinkage_features(self.terms, group, rows, state)
        family = model_family(self.model, self._x(group, mask), fs, gd, self.model.exponent)
        return mask, None, family

    def _names(self, state):
        names, units = list(self.model.param_names), list(self.model.units)
        _add_term_names(names, units, self.terms, state)
        return names, units

    def fit(self, group: Group, rows: np.ndarray, base: FitStart | None = None) -> Fitted:
        rows = np.asarray(rows, int)
        state: dict = {"terms": _prepare_terms(self.terms, group, rows)}
        sinkage_keeps_bekker(self.name, False, self.terms, state["terms"], group, rows)
        mask, _, family = self._inputs(group, rows, state)
        y, w = group.y[mask], group.w[mask]
        p = self.model.n_params
        if base is not None and isinstance(base.extension, ModelExtension):
            start = list(base.result.values[:p])
        else:
            assert self.model.start is not None  # check_own_model refused a model without
            start = list(self.model.start(self._x(group, mask), y))
        p0 = start + [0.0] * (family.size - p)
        names, units = self._names(state)
        bounds = self.model.bounds_of
        result = _identify(family, y, w, p0, names, units, bounds, self.name)
        return Fitted(self, result, state)

    def predict(self, fitted: Fitted, group: Group, rows: np.ndarray) -> np.ndarray:
        _, _, family = self._inputs(group, np.asarray(rows, int), fitted.state)
        return family.f(fitted.result.values)


# ----------------------------------------------------------------------------- shear models
@dataclass(frozen=True)
class ShearExtension(Extension):
    """Janosi–Hanamoto (Eq. 13) with covariate terms on c, tan φ, K and/or side walls."""

    terms: tuple[Term, ...] = ()
    side_walls: bool = False

    def _inputs(self, group, rows, state):
        mask = group.samples_of(rows)
        owner = group.owner[mask]
        states = state.get("terms", [])
        kw = {
            key: _stack(self.terms, states, group, owner, target)
            for target, key in (("c", "fc"), ("tan_phi", "ft"), ("K", "fk"))
        }
        counts = [0 if (f := kw[k]) is None else f.shape[1] for k in ("fc", "ft", "fk")]
        if self.side_walls:
            t = group.tests
            a = side_wall_ratio(t["r_inner_m"], t["r_outer_m"], t["grouser_height_m"])
            kw["a"] = np.asarray(a, float)[owner]
        layout = ShearLayout(counts[0], counts[1], counts[2], self.side_walls)
        return mask, layout, shear_family(layout, group.x["sigma"][mask], group.x["j"][mask], **kw)

    def _names(self, state):
        names, units = list(JANOSI.param_names), list(JANOSI.units)
        states = state.get("terms", [])
        for target in ("c", "tan_phi", "K"):
            extra = _term_names(self.terms, states, target, f"ln {target}-factor[{{}}]")
            names += extra
            units += ["-"] * len(extra)
        if self.side_walls:
            names.append("K0")
            units.append("-")
        return names, units

    def fit(self, group: Group, rows: np.ndarray, base: FitStart | None = None) -> Fitted:
        rows = np.asarray(rows, int)
        state: dict = {"terms": _prepare_terms(self.terms, group, rows)}
        check_shear_terms(self.name, self.terms, state["terms"], group, rows)
        mask, layout, family = self._inputs(group, rows, state)
        y, w = group.y[mask], group.w[mask]
        if base is not None:
            start = list(base.result.values[:3])
        else:
            start = list(janosi_start(group.x["sigma"][mask], group.x["j"][mask], y))
        if self.side_walls:
            # Start from intrinsic values: divide out the mean apparent-area factor.
            a_mean = float(np.mean(shear_inputs_a(group, rows)))
            start = [start[0] / (1 + a_mean), start[1], start[2]]
        p0 = start + [0.0] * (layout.size - len(start) - self.side_walls)
        p0 += [0.4] if self.side_walls else []
        names, units = self._names(state)
        bounds = {**JANOSI.bounds_of, "K0": (0, 1)}
        result = _identify(family, y, w, p0, names, units, bounds, self.name)
        return Fitted(self, result, state)

    def predict(self, fitted: Fitted, group: Group, rows: np.ndarray) -> np.ndarray:
        _, _, family = self._inputs(group, np.asarray(rows, int), fitted.state)
        return family.f(fitted.result.values)


def shear_inputs_a(group: Group, rows: np.ndarray) -> np.ndarray:
    """Side-wall ratio a of each of the tests ``rows``."""
    t = group.tests.iloc[np.asarray(rows, int)]
    return np.asarray(side_wall_ratio(t["r_inner_m"], t["r_outer_m"], t["grouser_height_m"]))
