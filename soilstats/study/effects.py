"""Does the factor change a per-test response?  ANOVA with blocks, Tukey pairs, relevance.

For each soil and response (one value per test, see :mod:`.responses`):

1. **ANOVA** of the response by the factor, with the spec's blocking factors that vary within
   the soil (type II two-way ANOVA, :func:`soilstats.statistics.anova_twoway`); without
   blocks, or when the factor is confounded with them (each method on its own test day), the
   one-way ANOVA (:func:`soilstats.statistics.anova_oneway`) — and the confounding is stated.
   When a block is declared random (``random_blocks``; by default the operator of a
   preparation study — the persons of the paper's Table 1, criterion 2, are a sample of those
   who will prepare the bin), the factor is tested against the factor × operator mean square
   (:func:`soilstats.statistics.anova_random_block`): a persistent bias of one person with
   one method then counts as error, not as a method effect.  Where that test cannot be made
   (one operator, no operator column, no interaction degrees of freedom) the test against the
   residual is used and a note says which and why; with no replicate inside the factor ×
   operator cells the residual *is* that interaction, and the note says so too.
2. **Tukey pairs** on the least-squares means of the blocked model
   (:func:`soilstats.statistics.tukey_lsmeans`, Tukey–Kramer), with the same error term as
   the F-test (the interaction mean square when the operators are random).
3. **Relevance**: the spec's margin (e.g. ±15 % pressure) against the largest pairwise
   difference and its simultaneous interval, so that an effect far smaller than a rover team
   cares about is not reported as one that matters merely because many tests resolve it.

The verdicts across soils and responses are then Holm-adjusted (:mod:`.verdict`).
"""

from __future__ import annotations

import zlib
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..identification.conditions import condition_label
from ..statistics import (
    ConfoundingError,
    StatisticsInputError,
    anova_oneway,
    anova_random_block,
    anova_twoway,
    effect_row,
    tukey_lsmeans,
    welch_random_block,
)

if TYPE_CHECKING:
    from ..statistics import TestResult
    from .spec import Response, StudySpec

__all__ = ["factor_effects"]


def _active_blocks(frame: pd.DataFrame, spec: StudySpec) -> list[str]:
    return [b for b in spec.blocks if b in frame.columns and frame[b].dropna().nunique() > 1]


def _random_test(
    data: pd.DataFrame,
    resp: str,
    factor: str,
    blocks: list[str],
    spec: StudySpec,
    soil: str,
    notes: list[str],
) -> pd.DataFrame | None:
    """The factor's ANOVA against the factor × random-block mean square, or None (noted)."""
    for block in spec.random_blocks:
        if block not in blocks:
            seen = data[block].dropna().nunique() if block in data.columns else 0
            why = f"one {block} only" if seen == 1 else f"no {block!r} recorded"
            notes.append(
                f"{soil}, {resp}: {why} — {factor} tested against the test-to-test scatter, "
                f"not against the {factor} × {block} mean square; the result holds for the "
                f"{block}(s) of these tests, whose own bias with a {factor} level cannot be "
                f"told from a {factor} effect"
            )
            continue
        try:
            return anova_random_block(data, resp, "level", blocks, block)
        except StatisticsInputError as err:
            if getattr(err, "column", None) == resp:  # no replicate within the cells
                notes.append(
                    f"{soil}, {resp}: no replicate within the {factor} × {block} cells, so the "
                    f"residual of the blocked ANOVA is the {factor} × {block} interaction: "
                    f"{factor} is tested against it ({block} random)"
                )
            else:
                notes.append(
                    f"{soil}, {resp}: {factor} tested against the test-to-test scatter, not "
                    f"against the {factor} × {block} mean square — {_first_line(err)}; a "
                    f"{block}'s own bias with a {factor} level may be read as a {factor} effect"
                )
    return None


def _stream(seed: int, soil: str, response: str) -> int:
    """A seed of its own for one (soil, response) test, derived from the study's ``seed``
    (stable across runs and platforms: crc32, not Python's salted ``hash``)."""
    return (int(seed) * 1_000_003 + zlib.crc32(f"{soil}/{response}".encode())) % 2**32


def _welch_test(
    data: pd.DataFrame,
    resp: str,
    factor: str,
    blocks: list[str],
    table: pd.DataFrame,
    soil: str,
    notes: list[str],
    seed: int,
) -> TestResult | None:
    """The Welch-type test with one variance per level (operators random), or None (noted).

    The pooled F against the factor × operator mean square assumes that every level's operator
    cell means scatter alike; the preparation methods do not (stiffness cv 0.08–0.32), and the
    pooled F then rejected a true null for soil01's pressure in 0.17 of the bundled design's
    campaigns.  The Welch-type test is liberal where they do scatter alike (0.08–0.11 for 3–13
    methods): the verdict takes the larger p of the two (docs/studies.md).
    """
    random = table.attrs["random"]
    try:
        named = data.drop(columns=factor).rename(columns={"level": factor})
        return welch_random_block(named, resp, factor, blocks, random, seed=seed)
    except (StatisticsInputError, ConfoundingError) as err:
        notes.append(
            f"{soil}, {resp}: {factor} tested with the pooled F against the {factor} × "
            f"{random} mean square, which assumes equal scatter of every {factor} — one "
            f"variance per {factor} could not be estimated: {_first_line(err)}"
        )
        return None


def _welch_row(result: TestResult, factor: str, soil: str, response: str) -> pd.DataFrame:
    return pd.DataFrame(
        [
            dict(
                soil=soil,
                response=response,
                term=f"{factor} (one variance per level)",
                df=result.df_num,
                F=result.statistic,
                **{"PR(>F)": result.p_value},
                error_term="parametric bootstrap (the larger p of this and the F decides)",
                test=result.test,
            )
        ]
    )


def _in_terms(err: Exception, factor: str) -> str:
    """The error's text with the factor's column name for the internal 'level' column."""
    return str(err).replace("column 'level'", f"column {factor!r}")


def _first_line(err: Exception) -> str:
    return str(err).splitlines()[0].rstrip(":;, ")


def _tidy_anova(table: pd.DataFrame, soil: str, response: str) -> pd.DataFrame:
    out = table.reset_index(names="term")
    out.insert(0, "response", response)
    out.insert(0, "soil", soil)
    out["test"] = table.attrs.get("test", "ANOVA")
    return out


def factor_effects(
    per_test: pd.DataFrame,
    spec: StudySpec,
    soil: str,
    alpha: float,
    *,
    seed: int = 0,
    **tukey: bool,
) -> dict:
    """ANOVA, Tukey pairs and relevance of every response of ``spec`` for one soil.

    Parameters
    ----------
    per_test : pandas.DataFrame
        One row per test of this soil, with the factor, block and response columns.
    spec : StudySpec
    soil : str
    alpha : float
        Level of the Tukey intervals (the study's α).
    seed : int, default 0
        Seed of the Welch-type test's parametric bootstrap (with a random block), combined
        with the soil and response so that each test draws its own stream.
    **tukey
        ``p_values=False`` (for :func:`soilstats.statistics.tukey_lsmeans`) skips the
        pairs' adjusted p-values (the verdicts read only the intervals: :mod:`.defaults`
        re-tests without them).

    Returns
    -------
    dict
        ``effects`` (rows for :func:`soilstats.statistics.verdicts`, with the relevance
        columns), ``anova`` (tidy ANOVA rows), ``pairs`` (Tukey rows), ``notes``, and
        ``untested`` (why a response could not be tested for want of repetitions; also in
        ``notes``).
    """
    factor = spec.factor
    frame = per_test.copy()
    frame["level"] = frame[factor].map(condition_label)
    effects, anovas, pairs, notes, untested = [], [], [], [], []
    for resp in spec.responses:
        data = frame.dropna(subset=[resp.name])
        dropped = len(frame) - len(data)
        if dropped:
            notes.append(f"{soil}, {resp.name}: {dropped} test(s) without a value left out")
        if data["level"].nunique() < 2:
            notes.append(f"{soil}, {resp.name}: fewer than two {factor} levels with values")
            continue
        unreplicated = _unreplicated(data, spec, soil, resp.name)
        if unreplicated:
            untested.append(unreplicated)
            notes.append(unreplicated)
            continue
        fitted = _anova(data, resp.name, factor, _active_blocks(data, spec), soil, notes)
        if fitted is None:
            continue
        table, blocks = fitted
        error, error_term = None, "Residual"
        if blocks:
            mixed = _random_test(data, resp.name, factor, blocks, spec, soil, notes)
            if mixed is not None:
                table, error, error_term = _against_random(mixed, factor)
        table = table.rename(index={"level": factor, "between": factor})
        welch = None
        if error is not None and data["level"].nunique() >= 3:
            welch = _welch_test(
                data, resp.name, factor, blocks, table, soil, notes, _stream(seed, soil, resp.name)
            )
        tidy = _tidy_anova(table, soil, resp.name)
        if welch is not None:  # the second test of the verdict, beside the pooled F
            tidy = pd.concat([tidy, _welch_row(welch, factor, soil, resp.name)])
        anovas.append(tidy)
        row = effect_row(soil, resp.name, factor, table)
        if welch is not None:
            # Intersection–union: an effect is declared only when both the pooled F (valid
            # when the levels scatter alike) and the Welch-type test (valid when they do not)
            # reject, so the level holds under either (docs/studies.md).  F, its effect size
            # and its error term stay in the row; the test column names both.
            row.update(
                p_value=max(row["p_value"], welch.p_value),
                p_pooled=row["p_value"],
                p_one_variance_per_level=welch.p_value,
                test=f"{row['test']}; and {welch.test}; the larger p decides",
            )
        row["blocks"] = ", ".join(blocks)
        row["n_tests"] = len(data)
        row["error_term"] = error_term
        residual = "within" if "within" in table.index else "Residual"
        row["df_error"] = error[1] if error is not None else float(table.loc[residual, "df"])  # type: ignore[arg-type]  # pandas-stubs: .loc[row, col] is any scalar
        try:
            tk = tukey_lsmeans(data, resp.name, "level", blocks, alpha=alpha, error=error, **tukey)
        except StatisticsInputError as err:
            notes.append(f"{soil}, {resp.name}: no pairwise comparison — {_in_terms(err, factor)}")
            tk = None
        row.update(_relevance(tk, resp))
        effects.append(row)
        if tk is not None:
            tk = tk.assign(soil=soil, response=resp.name)
            pairs.append(tk)
    return {
        "effects": effects,
        "anova": pd.concat(anovas, ignore_index=True) if anovas else pd.DataFrame(),
        "pairs": pd.concat(pairs, ignore_index=True) if pairs else pd.DataFrame(),
        "notes": notes,
        "untested": untested,
    }


def _anova(
    data: pd.DataFrame, response: str, factor: str, blocks: list[str], soil: str, notes: list[str]
) -> tuple[pd.DataFrame, list[str]] | None:
    """The ANOVA of ``response`` on the factor's levels (``level``) within ``blocks`` and the
    blocks it kept: one-way, with a note, where the factor is confounded with the blocks;
    None, with a note, where it cannot be tested."""
    try:
        if blocks:
            table = anova_twoway(data, response, "level", blocks)
        else:
            table = anova_oneway(data, response, "level")
    except ConfoundingError:
        joined = ", ".join(blocks)
        notes.append(
            f"{soil}: {factor} is confounded with {joined} — its levels cannot be told "
            f"apart from the {joined} they were tested in (e.g. a level tested in one "
            f"{joined} only), so the {factor} effect reported includes any {joined} effect "
            "(one-way ANOVA, no blocks)"
        )
        blocks = []
        table = anova_oneway(data, response, "level")
    except StatisticsInputError as err:
        notes.append(f"{soil}, {response}: not tested — {_in_terms(err, factor)}")
        return None
    return table, blocks


def _against_random(
    mixed: pd.DataFrame, factor: str
) -> tuple[pd.DataFrame, tuple[float, float], str]:
    """The random-block ANOVA ``mixed`` in the study's terms: (its table, its rows named by
    ``factor``; the error (mean square, df) the factor is tested against; that row's name)."""
    table = mixed
    inter = mixed.attrs["error_term"]
    error = (float(mixed.loc[inter, "mean_sq"]), float(mixed.loc[inter, "df"]))
    error_term = inter.replace("level", factor, 1)
    table["error_term"] = table["error_term"].str.replace("level", factor, n=1)
    table = table.rename(index={inter: error_term})
    table.attrs["test"] = (
        f"type II ANOVA, {factor} against {factor} × {mixed.attrs['random']} "
        f"({mixed.attrs['random']} random)"
    )
    return table, error, error_term


def _unreplicated(data: pd.DataFrame, spec: StudySpec, soil: str, response: str) -> str | None:
    """Why ``response`` cannot be tested when every factor level has one test, else None.

    The ANOVA needs at least one level with a repetition for its test-to-test scatter; said
    here in the study's own terms (factor column, soil, response, tests), not the ANOVA's.
    """
    counts = data.groupby("level").size()
    if counts.max() > 1:
        return None
    ids = data.set_index("level")["test_id"] if "test_id" in data.columns else None
    tests = ", ".join(
        f"{spec.factor} {lv}" + ("" if ids is None else f": {ids[lv]}") for lv in counts.index
    )
    return (
        f"{spec.name} study, soil {soil}, response {response}: each of the {len(counts)} "
        f"{spec.factor} levels has a single test ({tests}), so there is no test-to-test "
        f"scatter to test {spec.factor} against — repeat the tests of at least one of "
        f"these {spec.factor} levels (better: of each)"
    )


def _relevance(tk: pd.DataFrame | None, resp: Response) -> dict:
    """Largest pairwise difference, its simultaneous bound, and the margin they face."""
    if tk is None or tk.empty:
        return {"largest_difference": np.nan, "difference_bound": np.nan, "margin": np.nan}
    biggest = tk.loc[tk["meandiff"].abs().idxmax()]  # type: ignore[call-overload]  # pandas-stubs: idxmax is a Hashable label
    bound = float(np.maximum(tk["lower"].abs(), tk["upper"].abs()).max())
    margin = resp.margin_on_scale
    return {
        "largest_difference": float(abs(biggest["meandiff"])),
        "largest_pair": f"{biggest['group1']} vs {biggest['group2']}",
        "difference_bound": bound,
        "margin": np.nan if margin is None else margin,
        "margin_kind": resp.margin_kind if margin is not None else "",
    }
