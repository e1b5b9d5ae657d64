"""``CampaignFit``: a least-squares fit of pooled campaign tests, with the tests it used."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, fields
from functools import cached_property
from typing import TYPE_CHECKING, cast

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike
from scipy.special import stdtrit

from .._text import plural
from ..errors import InputError
from ..fitting.result import FitResult, HealthFlag
from ..models import MODELS
from ..outputs.files import json_safe
from ..quality.codes import CODES
from .bootstrap import MIN_TESTS, TestBootstrap
from .pooling import PooledData

if TYPE_CHECKING:
    from ..campaign.window import AppliedWindow
    from ..quality import ScreenedCampaign
    from ..quality.report import QualityReport

__all__ = ["CampaignFit"]


@dataclass(frozen=True)
class CampaignFit(FitResult):
    """A :class:`~soilstats.fitting.FitResult` of pooled tests (Section 2.1) plus ``tests``.

    ``tests`` has one row per test considered: ``test_id``, the samples it had and used, its
    weight, and why it was left out (``problem``); the columns differ for sinkage and shear
    (see :func:`~soilstats.identification.pool_sinkage`, :func:`~.pool_shear`).  The fitting
    layer knows nothing of campaigns; this is where the two meet.
    """

    #: The columns of ``tests`` as arrays (:attr:`PooledData.by_test`); None: no tests.
    test_columns: dict[str, np.ndarray] | None = field(default=None, repr=False)
    bootstrap: TestBootstrap | None = field(default=None, repr=False)
    data: dict = field(default_factory=dict, repr=False)

    @classmethod
    def of(
        cls,
        fit: FitResult,
        pooled: PooledData,
        notes: Iterable[str] = (),
        flags: tuple[HealthFlag, ...] | list[HealthFlag] = (),
        bootstrap: TestBootstrap | None = None,
        campaign: ScreenedCampaign | None = None,
    ) -> CampaignFit:
        """``fit`` with the tests it used (``pooled.tests``), the notes and flags of the
        pooling, the test-level bootstrap with the flags it raises, and (from ``campaign``)
        the data screening and fitting window behind its samples."""
        notes, flags = list(notes), list(flags)
        data: dict = {}
        if campaign is not None:
            more_notes, more_flags, data = data_findings(campaign, pooled.by_test["test_id"])
            notes += more_notes
            flags += more_flags
        if bootstrap is not None:
            more_notes, more_flags = _bootstrap_findings(fit, bootstrap)
            notes += more_notes
            flags += more_flags
        flags += _few_tests(pooled)
        base = fit.annotated(notes, flags)
        fields_ = {f.name: getattr(base, f.name) for f in fields(FitResult)}
        # each fit its own dict: the arrays are shared (read-only) by the fits of one campaign
        return cls(**fields_, test_columns=dict(pooled.by_test), bootstrap=bootstrap, data=data)

    @classmethod
    def deferred(
        cls, fit: FitResult, pooled: PooledData, finish: Callable[[], CampaignFit]
    ) -> CampaignFit:
        """``fit`` with its tests now and the rest (notes, flags, the test bootstrap, the data
        record) from ``finish()`` when first read: what a loop that reads ``params`` only
        skips.  ``finish`` returns the full :meth:`of` result the fields are taken from; its
        work is seeded, so the values are those an eager fit gives (issue #45, item 7)."""
        fields_ = {f.name: getattr(fit, f.name) for f in fields(FitResult)}
        out = cls(**fields_, test_columns=dict(pooled.by_test))
        out.__dict__["_pending"] = finish
        out.__dict__["_finishing"] = threading.Lock()  # this result's: others finish alongside
        return out

    def _finish(self) -> None:
        """Take the deferred fields from the pending ``finish`` (:meth:`deferred`), once."""
        if "_pending" not in self.__dict__:
            return
        with self.__dict__["_finishing"]:  # two threads reading it: one finishes, one waits
            finish = self.__dict__.get("_pending")
            if finish is None:
                return
            full = finish()
            for name in _DEFERRED:
                self.__dict__["_" + name] = full.__dict__["_" + name]
            del self.__dict__["_pending"]

    def __getstate__(self) -> dict:
        """Pickled (``--jobs`` workers) and copied finished: the pending work is a closure."""
        self._finish()
        return {k: v for k, v in self.__dict__.items() if k != "_finishing"}

    @cached_property
    def tests(self) -> pd.DataFrame | None:
        """One row per test considered (see the class docstring), built on first use."""
        return None if self.test_columns is None else pd.DataFrame(self.test_columns)

    @property
    def window(self) -> str:
        """The fitting window, in words ('none' when the whole record was used)."""
        return self.data.get("window_text", "none")

    @property
    def stderr_tests(self) -> pd.Series | None:
        """Test-level standard errors (cluster bootstrap over tests), or None if not run."""
        return None if self.bootstrap is None else self.bootstrap.stderr

    @property
    def stderr_level(self) -> str:
        """``"tests"`` where :attr:`stderr` is the test-level σ (the fit rests on
        :data:`~.bootstrap.MIN_TESTS` tests or more and the test bootstrap ran), else
        ``"eq4"``."""
        usable = self.bootstrap is not None and len(self.bootstrap.draws) > 1
        return "tests" if usable and self.n_tests >= MIN_TESTS else "eq4"

    @cached_property
    def stderr(self) -> pd.Series:
        """σ of each parameter: the test-level one (``stderr_tests``) where the fit rests on
        five tests or more and the bootstrap ran — what a new campaign of the same design
        would scatter by — else Eq. 4's (``stderr_eq4``). docs/conventions.md."""
        if self.stderr_level == "tests":
            return cast(pd.Series, self.stderr_tests).rename("stderr")
        return self.stderr_eq4

    @cached_property
    def stderr_eq4(self) -> pd.Series:
        """Eq. 4's σ (Eq. 3 from the covariance of Eqs. 4–5): the samples as the unit of
        replication. Printed beside :attr:`stderr` where the paper's tables are reproduced."""
        return pd.Series(self.stderr_values, index=self._index, name="stderr_eq4")

    def conf_int(self, alpha: float = 0.05, *, level: str = "auto") -> pd.DataFrame:
        """Two-sided (1 − alpha) intervals θ̂ ± t·σ.

        ``level="samples"``: Eq. 4's σ with t(N − Np), as :meth:`FitResult.conf_int` — right
        when the samples are the unit of replication.  ``level="tests"``: the test-level σ
        (``stderr_tests``, cluster bootstrap) with t(T − 1) for T tests, the usual small-
        sample allowance for a cluster-level standard error.  ``"auto"`` (default): the
        level of :attr:`stderr`.
        """
        if level == "auto":
            level = "tests" if self.stderr_level == "tests" else "samples"
        if level == "samples":
            return super().conf_int(alpha)
        if level != "tests":
            raise InputError(f"level must be 'samples' or 'tests', got {level!r}")
        if self.bootstrap is None:
            raise InputError(
                "no test-level interval without the test bootstrap: fit with test_resamples "
                "> 0 (e.g. 1000)"
            )
        if not 0 < alpha < 1:
            raise InputError(f"alpha must be in (0, 1), got {alpha!r}")
        t = stdtrit(max(self.bootstrap.n_tests - 1, 1), 1 - alpha / 2)
        half = t * self.stderr_tests  # type: ignore[operator]  # pandas-stubs: numpy float × Series is a Series
        return pd.DataFrame({"lower": self.params - half, "upper": self.params + half})

    def _parameter_table(self) -> pd.DataFrame:
        """The fit's table with the test-level σ beside Eq. 4's where the bootstrap ran."""
        table = super()._parameter_table()
        if self.bootstrap is not None:
            sd = cast(pd.Series, self.stderr_tests)
            table.insert(3, "stderr (tests)", [f"{sd[n]:.4g}" for n in self.param_names])
        return table

    @property
    def covariance_tests(self) -> np.ndarray | None:
        """Test-level covariance of the parameters: that of the test bootstrap's estimates
        (the scatter between repeated tests), or None without the bootstrap."""
        if self.bootstrap is None or len(self.bootstrap.draws) < 2:
            return None
        return np.atleast_2d(np.cov(self.bootstrap.draws, rowvar=False))

    # mypy: ``level`` narrows what the parent's **inputs would take under that name; a model
    # input is never called "level", so no call the parent accepts means something else here.
    def eval_uncertainty(  # type: ignore[override]
        self,
        x: ArrayLike | None = None,
        sigma: float = 1.0,
        *,
        level: str = "auto",
        **inputs: ArrayLike,
    ) -> np.ndarray:
        """``sigma`` standard deviations of the fitted curve at ``x`` (:meth:`eval`'s inputs)
        by the delta method, from the test-level covariance (``level="tests"``: what a new
        test of the soil scatters by, as the fit's stderr says) or Eq. 4's
        (``"samples"``); ``"auto"`` (default): the test-level one where the fit rests on
        :data:`~soilstats.identification.bootstrap.MIN_TESTS` tests or more and the test
        bootstrap ran, else Eq. 4's. Inputs by name as for :meth:`eval`."""
        if level not in ("auto", "tests", "samples"):
            raise InputError(f"level must be 'auto', 'tests' or 'samples', got {level!r}")
        tests = self.covariance_tests
        if level == "tests" and tests is None:
            raise InputError(
                "no test-level band without the test bootstrap: fit with test_resamples > 0"
            )
        use_tests = level == "tests" or (
            level == "auto" and tests is not None and self.n_tests >= MIN_TESTS
        )
        covariance = cast(np.ndarray, tests) if use_tests else self.covariance
        return self._band(x, sigma, covariance, **inputs)

    @property
    def n_tests(self) -> int:
        """Tests that contributed samples to the fit."""
        columns = self.test_columns
        if not columns:
            return 0
        if "used" in columns:
            return int((np.asarray(columns["used"]) > 0).sum())
        return len(next(iter(columns.values())))

    def to_dict(self) -> dict:
        out = super().to_dict() | {"tests": self.n_tests, "stderr_tests": None}
        out["stderr"] = json_safe(dict(self.stderr))
        out["stderr_eq4"] = json_safe(dict(self.stderr_eq4))
        out["stderr_level"] = self.stderr_level
        if self.bootstrap is not None:
            out["stderr_tests"] = json_safe(dict(cast(pd.Series, self.stderr_tests)))
        out["quality"] = self.data.get("quality")
        out["window"] = self.data.get("window")
        out["excluded"] = self.data.get("excluded", [])
        return out

    def _summary_parameters(self) -> list[str]:
        """The parameter lines: value, ``stderr`` (test-level where the fit rests on five
        tests or more, else Eq. 4's, said in the header), Eq. 4's beside a test-level one,
        and the 95 % t-interval of ``stderr``'s level."""
        if self.stderr_level != "tests":
            return super()._summary_parameters()
        bs = cast(TestBootstrap, self.bootstrap)  # test-level: the bootstrap ran
        lines = [
            f"{'param':>8} {'value':>14} {'stderr':>11} {'Eq. 4':>11} {'rel.':>8} "
            f"{f'95% CI (t, {bs.n_tests - 1} dof)':>27}  unit"
        ]
        ci = self.conf_int(0.05)
        for name in self.param_names:
            v, s, e = self.params[name], self.stderr[name], self.stderr_eq4[name]
            rel = abs(s / v) if v != 0 else np.inf
            lines.append(
                f"{name:>8} {v:>14.6g} {s:>11.4g} {e:>11.4g} {rel:>8.2%} "
                f"[{ci.loc[name, 'lower']:>12.5g},{ci.loc[name, 'upper']:>12.5g}]  "  # type: ignore[str-bytes-safe]  # pandas-stubs: .loc[row, col] is any scalar
                f"{self.units.get(name, '')}"
            )
        return lines

    def summary(self) -> str:
        text = super().summary()
        head, _, tail = text.rpartition("Health:")
        text = head + f"Window: {self.window}\n" + "Health:" + tail
        if self.stderr_level == "tests":
            bs = cast(TestBootstrap, self.bootstrap)
            sigma = (
                f"stderr: the test-level σ, sd of the estimates over {bs.n_resamples} "
                f"resamples of the {bs.n_tests} tests (cluster bootstrap, seed {bs.seed}, "
                f"{bs.n_failed} failed); Eq. 4's σ (samples as the unit) beside it."
            )
        elif self.n_tests < MIN_TESTS:
            sigma = (
                f"stderr: Eq. 4's σ: {plural(self.n_tests, 'test')} cannot measure the scatter "
                "between repeated tests, which it leaves out."
            )
        else:
            sigma = "stderr: Eq. 4's σ (no test bootstrap was run: test_resamples=0)."
        head, _, tail = text.rpartition("Notes:")
        return f"{head}{sigma}\nNotes:{tail}" if tail else f"{text}\n{sigma}"


class _Deferred:
    """A field of :class:`CampaignFit` that :meth:`CampaignFit.deferred` fills on first read
    (kept in the instance's ``__dict__`` as ``_<name>``)."""

    def __init__(self, name: str) -> None:
        self.slot = "_" + name

    def __get__(self, obj: CampaignFit | None, owner: type | None = None) -> object:
        if obj is None:
            return self
        obj._finish()
        return obj.__dict__[self.slot]

    def __set__(self, obj: CampaignFit, value: object) -> None:
        obj.__dict__[self.slot] = value  # the dataclass __init__ (and replace) set it so


#: The fields a deferred fit sets on first read: everything the test bootstrap and the
#: adequacy checks decide.
_DEFERRED = ("notes", "extra_flags", "bootstrap", "data")
for _name in _DEFERRED:
    setattr(CampaignFit, _name, _Deferred(_name))


#: Screening codes that are findings of a fit (the samples of the excluded codes are left out
#: in the default mode and only noted; load-capped, a stop code, is a note: a fact of the
#: design).
_FIT_CODES = tuple(code for code, q in CODES.items() if q.nature != "stop")


#: A window cuts a ``bearing-failure`` off (resolves it) when its z_max lies at most this
#: much (relative) above the onset: the proposals print the onset rounded up to 4
#: significant digits (at most 0.1 % above it), which must resolve what they propose.
ONSET_TOLERANCE = 1e-3


def data_findings(
    campaign: ScreenedCampaign, test_ids: Iterable[str]
) -> tuple[list[str], list[HealthFlag], dict]:
    """Notes, health flags and the JSON record of the screening and window behind a fit.

    A ``bearing-failure`` whose onset the window cuts off is resolved (a note, no flag);
    an unresolved one's flag names the window ``soilstats check`` proposes for its tests.
    """
    ids = [str(t) for t in test_ids]
    notes: list[str] = []
    flags: list[HealthFlag] = []
    record: dict = {"quality": None, "window": None, "excluded": [], "window_text": "none"}
    applied = campaign.window
    z_limit = {} if applied is None else _window_record(applied, ids, record, notes)
    report = campaign.report
    mine = report.flags_of(ids)
    record["quality"] = report.mode
    excluded = [f for f in mine if f.excluded]
    kept = [f for f in mine if not f.excluded]
    record["excluded"] = [
        {"test_id": f.test_id, "code": f.code, "rows": list(f.rows)} for f in excluded
    ]
    if excluded:
        by_code: dict[str, set] = {}
        for f in excluded:
            by_code.setdefault(f.code, set()).add(f.test_id)
        notes.append(
            f"Data quality ({report.mode}): {sum(len(f.rows) for f in excluded)} samples left "
            "out ("
            + ", ".join(f"{code} in {plural(len(t), 'test')}" for code, t in by_code.items())
            + "; their rows are listed as excluded)."
            + (" z re-zeroed at the contact found." if "pre-contact" in by_code else "")
        )
    capped = {f.test_id for f in mine if f.code == "load-capped"}
    if capped:
        notes.append(
            f"load-capped: {len(capped)} tests stopped at one load, so their depth is an "
            "outcome of stiffness; compare per-test exponents with the pooled one."
        )
    for code in _FIT_CODES:
        hits = [f for f in kept if f.code == code]
        # A finding whose samples the window cut off is resolved: a bearing failure past the
        # window's z_max (its onset rounded up, as proposed), or any flag whose rows the window
        # (z_max or p_max) left out, every one.
        limit = 1 + ONSET_TOLERANCE
        cut = [
            f
            for f in hits
            if (applied is not None and applied.cuts(f.rows))
            or (
                code == "bearing-failure"
                and z_limit.get(f.test_id, np.inf) <= cast(float, f.value) * limit
            )  # a bearing failure has its onset
        ]
        if cut:
            notes.append(
                f"{code} in {plural(len({f.test_id for f in cut}), 'test')} lies outside the "
                "window (resolved)."
            )
        hits = [f for f in hits if f not in cut]
        if hits:
            tests_hit = sorted({f.test_id for f in hits})
            advice = _proposed_items(report, tests_hit) if code == "bearing-failure" else ""
            flags.append(
                HealthFlag(
                    code,
                    f"{len(tests_hit)} of {plural(len(ids), 'test')} ({', '.join(tests_hit[:5])}"
                    f"{', …' if len(tests_hit) > 5 else ''}): {hits[0].message}" + advice,
                )
            )
    return notes, flags, record


def _window_record(applied: AppliedWindow, ids: list[str], record: dict, notes: list[str]) -> dict:
    """The fitting window behind a fit into ``record`` (its rules, the samples outside it by
    test) and ``notes``; returns each test's z_max [m]."""
    per = applied.per_test[applied.per_test["test_id"].isin(ids)]
    z_limit = dict(zip(per["test_id"], per["z_max"], strict=True))
    outside = int(per["outside"].sum())
    record["window"] = {
        "rules": applied.window.to_dict(),
        "outside": {t: int(n) for t, n in zip(per["test_id"], per["outside"], strict=True) if n},
    }
    record["window_text"] = applied.window.describe()
    notes.append(
        f"Fitting window {applied.window.describe()}: {outside} samples of "
        f"{int((per['outside'] > 0).sum())} tests outside it, not used."
    )
    return z_limit


def _proposed_items(report: QualityReport, tests_hit: list[str]) -> str:
    """The ``--z-max`` items ``soilstats check`` proposes for these failed tests."""
    windows = report.proposed_windows()
    if not len(windows):
        return ""
    tests = report.tests.assign(test_id=report.tests["test_id"].astype(str))
    plates = tests[tests["test_id"].isin(tests_hit)][["soil", "b_m"]]
    mine = (windows["scope"] == "test") & windows["test_id"].isin(tests_hit)
    for soil, b in plates.drop_duplicates().itertuples(index=False):
        same_b = (windows["b_m"] == b) | (windows["b_m"].isna() & pd.isna(b))
        mine |= (windows["scope"] == "plate") & (windows["soil"] == soil) & same_b
    items = " ".join(windows.loc[mine, "z_max_item"]).split()
    if not items:
        return ""
    shown = " ".join(f"--z-max {i}" for i in items[:6]) + (" …" if len(items) > 6 else "")
    return f"; proposed window (soilstats check): {shown}"


#: The test-level σ exceeds Eq. 4's by more than this factor: flag it.  One-sided: a
#: test-level σ below Eq. 4's leaves Eq. 4 the safer error bar, and with few tests the
#: bootstrap's own sd is noisy (5 clean tests: ratios 0.34–1.32, so a two-sided check fired
#: on 9 of 40 clean campaigns).
DISAGREEMENT = 2.0


def _signed() -> set[str]:
    """Parameters whose sign is a physical statement (a modulus that may be either sign):
    those the model records name (``Model.signed``: kc, kphi, k1, k2, c)."""
    return {name for model in MODELS.values() for name in model.signed}


#: Below this share of resamples keeping the estimate's sign, the sign is not determined.
MIN_SIGN_STABILITY = 0.9
#: More resamples than this share not converging: the test-level σ is not to be trusted.
MAX_FAILED_SHARE = 0.05
#: The bootstrap sd over this multiple of the central 68 % half-width: a few resamples carry
#: it, and its value moves with the seed (GRC-1's Bekker kφ: 13.9×, sd 1.3e5–9.7e5 over
#: seeds 0–4).  Clean simulated campaigns reach 1.7 at most (48 fits, 200 resamples each).
MAX_TAIL_RATIO = 3.0


def _few_tests(pooled: PooledData) -> list[HealthFlag]:
    """``few-tests`` when the fit rests on fewer tests than a test bootstrap needs: its σ is
    then one set of curves' (Eq. 4), and nothing measures the scatter between repeats."""
    n = int(np.unique(pooled.test_index).size)
    if n >= MIN_TESTS:
        return []
    what = "one test" if n == 1 else f"{n} tests"
    return [
        HealthFlag(
            "few-tests",
            f"{what}: too few to measure the scatter between repeated tests (a test "
            f"bootstrap needs {MIN_TESTS}), so the ± is Eq. 4's alone and leaves that scatter "
            "out (on Cullinan sand it is 7× one curve's σ of n); repeat the test before "
            "quoting a σ",
        )
    ]


def _sign_decided_by_eq4_only(fit: FitResult, sd: pd.Series, n_tests: int) -> list[str]:
    """The signed parameters whose sign Eq. 4's 95 % interval decides and the test-level
    one does not (both intervals in words), where the test-level σ is the larger by more
    than :data:`DISAGREEMENT`: the one conclusion the two σ can differ on for a fit."""
    eq4 = fit.conf_int(0.05)
    t = stdtrit(max(n_tests - 1, 1), 0.975)
    out = []
    for name in fit.param_names:
        if name not in _signed() or not np.isfinite(sd[name]):
            continue
        if not sd[name] > DISAGREEMENT * fit.stderr[name]:
            continue
        lo, hi = eq4.loc[name, "lower"], eq4.loc[name, "upper"]
        v = fit.params[name]
        t_lo, t_hi = v - t * sd[name], v + t * sd[name]
        if (lo > 0 or hi < 0) and t_lo <= 0 <= t_hi:  # type: ignore[arg-type, operator]  # pandas-stubs: .loc[row, col] is any scalar
            out.append(
                f"{name} ({lo:.3g} to {hi:.3g}), the tests do not ({t_lo:.3g} to {t_hi:.3g})"  # type: ignore[str-bytes-safe]  # pandas-stubs: .loc[row, col] is any scalar
            )
    return out


def _bootstrap_findings(fit: FitResult, bs: TestBootstrap) -> tuple[list[str], list[HealthFlag]]:
    notes = [
        # One wording for every set of a campaign (the number of tests is the fit's own
        # field), so a report prints it once.
        f"Test-level σ: the sd of the estimates over {bs.n_resamples} cluster-bootstrap "
        f"resamples of the tests (seed {bs.seed}); Eq. 4's σ assumes independent samples."
    ]
    flags = []
    sd, half = bs.stderr, bs.central_halfwidth  # each a pass over the resamples
    ratio = (sd / fit.stderr).to_numpy()
    off = [
        f"{name} {r:.2g}×"
        for name, r in zip(fit.param_names, ratio, strict=True)
        if np.isfinite(r) and r > DISAGREEMENT
    ]
    if off and bs.n_tests < MIN_TESTS:
        # From five tests on stderr is the test-level σ and stderr_eq4 stands beside it in
        # every table: the ratio is on the face of the output and needs no note.
        notes.append(
            f"The tests scatter more than their samples say: the test-level σ is more than "
            f"{DISAGREEMENT:g}× Eq. 4's ({', '.join(off)})"
            + ("; stderr is the test-level σ." if bs.n_tests >= MIN_TESTS else ".")
        )
    decided = _sign_decided_by_eq4_only(fit, sd, bs.n_tests)
    if decided:
        flags.append(
            HealthFlag(
                "test-scatter",
                f"Eq. 4's σ would decide the sign of {'; '.join(decided)}: quote stderr (the "
                "test-level σ), never stderr_eq4, for that sign",
            )
        )
    stability = bs.sign_stability()
    signed = _signed()
    unstable = [
        f"{name} keeps its sign in {share:.0%}"
        for name, share in stability.items()
        if name in signed and np.isfinite(share) and share < MIN_SIGN_STABILITY
    ]
    if unstable:
        flags.append(
            HealthFlag(
                "sign-unstable",
                f"over resamples of the tests {', '.join(unstable)} of them: the tests do not "
                "determine it (with kc/kphi: the plate sizes do not separate them); do not "
                "extrapolate to other contact widths",
            )
        )
    unstable_why = []
    if bs.n_failed > MAX_FAILED_SHARE * bs.n_resamples:
        unstable_why.append(
            f"{bs.n_failed} of {bs.n_resamples} resamples of the tests did not converge "
            "or could not determine the parameters (e.g. they drew tests of one plate size "
            "or one normal pressure)"
        )
    heavy = [
        f"{name} sd {sd[name]:.3g} is {r:.1f}× the central 68 % half-width {half[name]:.3g}"  # type: ignore[call-overload]  # pandas-stubs: a label is Hashable (ours are str)
        for name, r in (sd / half).items()
        if np.isfinite(r) and r > MAX_TAIL_RATIO
    ]
    if heavy:
        unstable_why.append(
            f"a few resamples carry stderr_tests ({'; '.join(heavy)}), so its value moves "
            "with the seed; quote neither stderr_tests nor Eq. 4's stderr for these"
        )
    if unstable_why:
        flags.append(
            HealthFlag(
                "bootstrap-unstable",
                "; ".join(unstable_why) + ": the estimate depends on which tests are in the "
                "campaign",
            )
        )
    return notes, flags
