"""``fit_sinkage``: the paper's pressure–sinkage identification (Section 2.1, Eqs. 6–11)."""

from __future__ import annotations

import contextlib
import functools
import weakref
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Literal

import numpy as np

from .._text import plural
from ..campaign.window import FitWindow
from ..errors import IdentifiabilityError, InputError, ModelError
from ..fitting.identify import identify
from ..fitting.result import FitResult, HealthFlag
from ..models import Model, get_model
from ..quality import screened
from .adequacy import adequacy_findings, test_forms
from .bootstrap import TestBootstrap, test_bootstrap
from .centring import centred
from .pooling import PooledData, pool_sinkage
from .result import CampaignFit
from .reuse import frozen_argument, reusable

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..campaign.tables import Criterion
    from ..quality import ScreenedCampaign

__all__ = ["fit_sinkage", "pool_sinkage"]

_COUNTS = {2: "two", 3: "three", 4: "four"}


def _check_identifiable(spec: Model, pooled: PooledData) -> None:
    """The plate sizes the model's record asks for (``Model.min_plate_sizes``)."""
    tests = pooled.by_test  # the plate sizes of the tests with samples: one per test, not sample
    sizes = np.unique(tests["b_m"][tests["used"] > 0])
    needed = spec.min_plate_sizes
    if sizes.size < needed:
        have = "one" if sizes.size == 1 else str(sizes.size)
        raise IdentifiabilityError(
            f"the {spec.name} model needs tests with at least {_COUNTS.get(needed, needed)} "
            f"plate sizes b to separate its size terms (Section 2.1); the selection has "
            f"{have} (b = {', '.join(f'{b:g}' for b in sizes)} m). "
            "Fit model='bernstein' instead, or add tests with another plate size."
        )


def _notes(pooled: PooledData, points_per_test: int | None, weighting: str) -> list[str]:
    g = pooled.by_test  # arrays: the frame's lookups cost more than these sums
    n_tests = len(g["test_id"])
    notes = [
        f"{plural(n_tests, 'test')} pooled ({', '.join(map(str, g['test_id'][:6]))}"
        f"{', …' if n_tests > 6 else ''}); plate sizes b = "
        f"{', '.join(f'{b:g}' for b in np.unique(g['b_m']))} m.",
        (
            "Weights w = 1/max(p) per test (Section 2.1), so each test's pressures span 0..1."
            if weighting == "max-pressure"
            else "Unit weights (weighting='none')."
        ),
        (
            f"Up to {points_per_test} samples per test, nearest to equally spaced sinkages "
            f"(Section 2.1): {int(g['used'].sum())} of {int(g['samples'].sum())} used."
            if points_per_test
            else f"All {int(g['used'].sum())} samples with z > 0 used."
        ),
    ]
    dropped = int(g["excluded_z_nonpositive"].sum())
    if dropped:
        notes.append(
            f"{dropped} samples with z <= 0 excluded (z^n undefined; counted per test)."
        )
    return notes


@reusable
def fit_sinkage(
    campaign: Campaign,
    model: str | Model = "bekker",
    *,
    method: Literal["lm", "wong"] = "lm",
    points_per_test: int | None = 100,
    weighting: Literal["max-pressure", "none"] = "max-pressure",
    p0: Sequence[float] | np.ndarray | None = None,
    on_failure: Literal["raise", "warn"] = "raise",
    test_resamples: int | Literal["auto"] = "auto",
    seed: int = 0,
    quality: Literal["off", "flag", "clean"] = "clean",
    window: FitWindow | None = None,
    **selection: Criterion,
) -> CampaignFit:
    """Identify Bekker (Eq. 7), Bernstein (Eq. 8) or Reece parameters from sinkage tests.

    Parameters
    ----------
    campaign : Campaign
        From :func:`soilstats.load_campaign`.
    model : str or Model
        A registered sinkage model (``"bekker"``, ``"bernstein"``, ``"reece"`` or one's
        own, :func:`soilstats.register_model`); its record gives the inputs, the starting
        values and the plate sizes needed.
    method : {"lm", "wong"}
        ``"lm"``: the paper's weighted Levenberg–Marquardt (Eq. 9) with σ from Eq. 3–5.
        ``"wong"``: Wong's p²-weighted log–log regression, for comparison (Fig. 3).
    points_per_test, weighting
        See :func:`pool_sinkage`.
    p0 : sequence, optional
        Starting values; by default Wong's estimate (a closed-form linear solve).
    test_resamples : int or "auto", default "auto"
        Resamples of the cluster bootstrap over tests. Where the fit rests on five tests or
        more, ``stderr`` is the test-level σ this gives (Eq. 4's stays as ``stderr_eq4``;
        docs/conventions.md); "auto" runs 200 resamples there (~10 ms) and none below five
        tests (``stderr`` is then Eq. 4's, and the ``few-tests`` flag says the scatter
        between tests was not measured); 0: never (``stderr`` is Eq. 4's).
    seed : int, default 0
        Seed of the bootstrap.
    quality : {"off", "flag", "clean"}, default "clean"
        Data screening (:func:`soilstats.quality.screen`) unless ``campaign`` was screened
        already: ``clean`` leaves spikes and pre-contact samples out; every other finding of
        the fit's tests becomes a health flag.
    window : FitWindow, optional
        Fitting window (z_max, p_max; global or per test-log column value), applied before
        the equal-sinkage thinning; stated in the summary.
    **selection
        Test-log filters, e.g. ``soil="soil01", velocity_m_s=4.8e-3``; must leave one soil.

    Returns
    -------
    CampaignFit
        A :class:`~soilstats.fitting.FitResult` with ``params``/``stderr`` indexed
        ``kc, kphi, n`` / ``k, n`` / ``k1, k2, n``; ``tests`` holds the per-test bookkeeping
        (samples used, excluded, weight).
    """
    spec = get_model(model, "sinkage")
    if method not in ("lm", "wong"):
        raise InputError(f"method must be 'lm' or 'wong', got {method!r}")
    campaign = screened(campaign, quality).windowed(window)
    pooling = {"points_per_test": points_per_test, "weighting": weighting, **selection}
    pooled, x, start = _prepared(spec, campaign, pooling)
    z, p, w = pooled.x["z_m"], pooled.y, pooled.weights

    if method == "wong":
        return _fit_wong(spec, campaign, pooled, x, points_per_test, weighting)

    if p0 is None:
        p0 = start()
    result = centred(identify(spec, x, p, p0, weights=w, on_failure=on_failure), z)

    def finish() -> CampaignFit:
        # The test bootstrap (3/4 of an eager fit) and the adequacy checks run when the
        # result's σ, flags, notes or summary are first read, not for a loop over params.
        notes = _notes(pooled, points_per_test, weighting)
        bootstrap = test_bootstrap(spec, x, pooled, result, test_resamples, seed, notes)
        flags = _adequacy(spec, pooled, result, bootstrap)
        flags += _rezero_sensitivity(spec, campaign, window, pooling, pooled, result, bootstrap, p0)
        return CampaignFit.of(result, pooled, notes, flags, bootstrap, campaign)

    return CampaignFit.deferred(result, pooled, finish)


#: What a fit of a campaign object derives from its data before the fit (see
#: :func:`_prepared`): campaign → {(pooling, model) → (model, pooled, x, start)}.
_PREPARED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()

#: Pooling arguments (selections) remembered per campaign object; the oldest is forgotten.
_PREPARED_PER_CAMPAIGN = 16


def _prepared(
    spec: Model, campaign: ScreenedCampaign, pooling: dict
) -> tuple[PooledData, np.ndarray, Callable[[], np.ndarray]]:
    """The pooled data (:func:`pool_sinkage` with ``pooling``), the model's x and a callable
    giving its starting values, kept per campaign object and arguments.

    A loop of fits of one campaign (models, p0, seeds, bootstrap sizes) pools the same
    samples and starts from the same Wong estimate every time: that work was 0.5 ms of a
    1.2 ms paper-size fit whose core is 0.5 ms. A campaign is never modified (the contract
    the campaign index and the screening cache rest on), so the same campaign object and
    arguments give the same arrays; they are made read-only, as every caller gets the same
    ones. The start is computed when first asked for (a given ``p0`` or ``method="wong"``
    never needs it). Arguments that cannot be compared (an array in the selection) are
    pooled afresh.
    """
    try:
        key = (frozen_argument(pooling), ("model", spec.name, id(spec)))
    except TypeError:
        key = None
    memo = _PREPARED.setdefault(campaign, {}) if key is not None else {}
    hit = memo.get(key)
    if hit is not None and hit[0] is spec:  # the record itself held: its id is not reused
        return hit[1:]
    pooled = pool_sinkage(campaign, **pooling)
    _check_identifiable(spec, pooled)
    _read_only(pooled.y, pooled.weights, pooled.test_index, *pooled.x.values())
    _read_only(*(v for v in pooled.by_test.values() if isinstance(v, np.ndarray)))
    x = _read_only(spec.x_from(pooled.x))[0]
    if spec.start is None:

        def start():
            raise ModelError(f"model {spec.name!r} states no starting values: pass p0")

    else:
        start = functools.cache(lambda: _read_only(np.asarray(spec.start(x, pooled.y)))[0])  # type: ignore[misc]  # spec.start is set in this branch (a lambda loses the narrowing)
    if key is not None:
        if len(memo) >= _PREPARED_PER_CAMPAIGN:
            with contextlib.suppress(RuntimeError, StopIteration, KeyError):  # another thread
                del memo[next(iter(memo))]
        memo[key] = (spec, pooled, x, start)
    return pooled, x, start


def _read_only(*arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    for values in arrays:
        values.flags.writeable = False
    return arrays


def _fit_wong(
    spec: Model,
    campaign: ScreenedCampaign,
    pooled: PooledData,
    x: np.ndarray,
    points_per_test: int | None,
    weighting: str,
) -> CampaignFit:
    """The fit by Wong's p²-weighted log–log regressions (``method="wong"``, Fig. 3): a
    closed form with the linearised regressions' σ, not Eq. 4's, centred and checked for
    adequacy as the LM fit is (no test bootstrap)."""
    z, p, w = pooled.x["z_m"], pooled.y, pooled.weights
    notes = _notes(pooled, points_per_test, weighting)
    if spec.wong is None:
        raise ModelError(
            f"Wong's method is not defined for the {spec.name} model; it is for "
            "the Bekker and Bernstein models"
        )
    theta, cov, n_nonpos = spec.wong(x, p)
    notes.append(
        "Wong's method: ln p on ln z weighted by p^2; sigma from the linearised "
        f"regressions, not Eq. 4. {n_nonpos} samples with p <= 0 have no log and were excluded."
    )
    closed = FitResult.closed_form(
        spec,
        theta,
        cov,
        w * (p - spec.func(x, *theta)),
        w * p,
        name=f"{spec.name} (Wong)",
        method="Wong: p^2-weighted log-log regression",
        message="closed-form linear regressions",
        x=x,
        y=p,
    )
    closed = centred(closed, z)
    flags = _adequacy(spec, pooled, closed, None)
    return CampaignFit.of(closed, pooled, notes, flags, campaign=campaign)


#: Re-zeroing at a seating contact that moves a parameter by more than this many of its
#: σ (test-level where a bootstrap over tests gave one, else Eq. 4's) is stated in the fit.
REZERO_SIGMAS = 1.0


def _rezero_sensitivity(
    spec: Model,
    campaign: ScreenedCampaign,
    window: FitWindow | None,
    pooling: dict,
    pooled: PooledData,
    result: FitResult,
    bootstrap: TestBootstrap | None,
    p0: Sequence[float] | np.ndarray,
) -> list:
    """``rezero-sensitive`` when the fit's tests include records re-zeroed at a seating
    contact and the same fit on the records as logged (toes kept, z unchanged) differs by
    more than :data:`REZERO_SIGMAS` σ in some parameter. ``pooling``: :func:`pool_sinkage`'s
    arguments of the fit (sample rule, weighting and the test selection)."""
    report = campaign.report
    ids = {str(t) for t in pooled.by_test["test_id"]}
    rezeroed = sorted(ids & report.rezeroed)
    if not rezeroed or report.unseated is None:
        return []
    logged = report.unseated().windowed(window)
    other = pool_sinkage(logged, **pooling)
    x = spec.x_from(other.x)
    alt = identify(spec, x, other.y, p0, weights=other.weights, on_failure="warn")
    if not alt.converged:
        return []
    sigma = bootstrap.stderr if bootstrap is not None else result.stderr
    moved = (result.params - alt.params) / sigma
    worst = moved.abs().idxmax()
    if not abs(moved[worst]) > REZERO_SIGMAS:  # type: ignore[call-overload]  # pandas-stubs: idxmax is a Hashable label (here a parameter name)
        return []
    which = "test-level" if bootstrap is not None else "Eq. 4"
    level = ""
    if bootstrap is None and "n" in result.params.index:
        # Without the test bootstrap (a posterior's start) the test-level σ of n still comes
        # from the tests' own n, so the message quotes it as identify's does (#46).
        own = test_forms(pooled.x["z_m"], pooled.y, pooled.test_index).n
        own = own[np.isfinite(own)]
        if own.size >= 3 and np.std(own, ddof=1) > 0:
            sigma_n = float(np.std(own, ddof=1) / np.sqrt(own.size))
            shift = float(result.params["n"] - alt.params["n"])
            level = f"; n moves {shift / sigma_n:+.1f} test-level σ (σ = {sigma_n:.2g})"
    return [
        HealthFlag(
            "rezero-sensitive",
            f"{plural(len(rezeroed), 'test')} re-zeroed at a seating contact "
            f"({', '.join(rezeroed[:4])}{', …' if len(rezeroed) > 4 else ''}) move "
            f"{worst} by {moved[worst]:+.1f} {which} σ ({alt.params[worst]:.4g} with z as "  # type: ignore[call-overload]  # pandas-stubs: idxmax is a Hashable label (here a parameter name)
            f"logged, {result.params[worst]:.4g} re-zeroed){level}; the fit uses the "  # type: ignore[call-overload]  # pandas-stubs: idxmax is a Hashable label (here a parameter name)
            "re-zeroed records: check the contacts with soilstats check",
        )
    ]


def _adequacy(
    spec: Model, pooled: PooledData, fit: FitResult, bootstrap: TestBootstrap | None
) -> list:
    """``lack-of-fit``, ``plate-exponents`` and (with the test bootstrap) ``aggregation-bias`` flags
    (identification/adequacy.py)."""
    b = pooled.x["b_m"] if "b_m" in spec.columns else None
    se_n = None if bootstrap is None else float(bootstrap.stderr["n"])
    n = float(fit.values[fit.param_names.index("n")])  # not fit.params: a pandas Series
    return adequacy_findings(pooled.x["z_m"], pooled.y, pooled.test_index, n, b, se_n)[1]
