"""Extensions whose terms the design cannot separate from the base model's parameters.

A stiffness factor per level of a column whose levels each hold one plate width gives every
plate a stiffness of its own, so Eq. 7's kc/b + kφ has one number left to set with two
parameters; the fit then walks along the redundant direction.  Such an extension is fitted on
Eq. 8's one k instead, and terms that are redundant among themselves (or c and tan φ factors
per level of a column that fixes the normal stress) are refused before any fit.  The groups
are built here from closed forms, so the truth is known exactly.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from soilstats.discovery.data import Group
from soilstats.discovery.extensions import Features, ShearExtension, SinkageExtension, Term
from soilstats.discovery.library import combine, library
from soilstats.errors import IdentifiabilityError

KC, KPHI, N = 2.0e4, 8.0e5, 1.1  # Eq. 7 [N/m^(n+1)], [N/m^(n+2)], [-]
TOOL_FACTOR = {"small": 1.0, "medium": 1.3, "large": 0.8}
OP_FACTOR = (1.0, 1.15)  # a stiffness factor per operator (0, 1)
WIDTH = {"small": 0.025, "medium": 0.05, "large": 0.075}  # b [m]


def _sinkage_group(noise: float = 0.0) -> Group:
    """Three round plates, four tests each: p = (kc/b + kφ)·f_tool·f_op·z^n, times
    1 + ``noise``·N(0, 1) per sample (seeded)."""
    rng = np.random.default_rng(7)
    z = np.linspace(0.002, 0.04, 30)
    rows, xs, ys, ws, owner = [], [], [], [], []
    for tool, b in WIDTH.items():
        for rep in range(4):
            p = (KC / b + KPHI) * TOOL_FACTOR[tool] * OP_FACTOR[rep % 2] * z**N
            p = p * (1 + noise * rng.standard_normal(z.size))
            owner.append(np.full(z.size, len(rows)))
            # operator: two per tool, so operator × tool nests within tool (and determines it)
            rows.append(
                {
                    "test_id": f"{tool}-{rep}",
                    "tool": tool,
                    "b_m": b,
                    "aspect_ratio": 1.0,
                    "op": rep % 2,
                }
            )
            xs.append(np.column_stack([z, np.full(z.size, b)]))
            ys.append(p)
            ws.append(np.full(z.size, 1 / p.max()))
    tests = pd.DataFrame(rows)
    tests["op_tool"] = tests["op"].astype(str) + " × " + tests["tool"]
    x = np.vstack(xs)
    return Group(
        "sinkage",
        "s",
        tests,
        {"z": x[:, 0], "b": x[:, 1]},
        np.concatenate(ys),
        np.concatenate(ws),
        np.concatenate(owner),
    )


def _per_level(column, targets=("k",)) -> SinkageExtension:
    return SinkageExtension(
        f"{column} (levels)", False, f"{targets} per {column}", bekker=True,
        terms=(Term(Features(column, "levels"), targets),),
    )  # fmt: skip


def test_stiffness_per_plate_width_level_drops_kc_kphi_for_one_k():
    """Levels that each hold one plate width: Eq. 8's k with a factor per level (operator's
    effect left in the data: it averages into each tool's factor, as the tests are
    balanced); the fit converges, is not rank-deficient, and its n is the truth."""
    group = _sinkage_group()
    rows = np.arange(len(group.tests))
    fitted = _per_level("tool").fit(group, rows)
    result = fitted.result
    assert fitted.state["bekker"] is False
    assert list(result.param_names[:2]) == ["k", "n"]
    assert result.converged
    assert not [f for f in result.flags if f.code == "rank-deficient"]
    assert result.values[1] == pytest.approx(N, rel=1e-6)
    # The factors are the ratios of the tools' stiffnesses to the reference tool's.
    state = fitted.state["terms"][0]
    k_of = {t: (KC / WIDTH[t] + KPHI) * TOOL_FACTOR[t] for t in WIDTH}
    ratios = [np.log(k_of[t] / k_of[state["reference"]]) for t in state["levels"]]
    assert result.values[2:] == pytest.approx(ratios, abs=0.01)


def test_stiffness_levels_that_do_not_fix_the_width_keep_bekker():
    """Levels that hold several plate widths leave kc/b + kφ something to set: Eq. 7 stays,
    and the operator's factor is found (1 % noise per sample)."""
    group = _sinkage_group(noise=0.01)
    fitted = _per_level("op").fit(group, np.arange(len(group.tests)))
    assert "bekker" not in fitted.state
    assert list(fitted.result.param_names[:3]) == ["kc", "kphi", "n"]
    assert fitted.result.converged
    state = fitted.state["terms"][0]
    sign = 1 if state["reference"] == 0 else -1
    assert fitted.result.values[3] == pytest.approx(sign * np.log(OP_FACTOR[1]), abs=0.02)


def test_exponent_offsets_per_width_level_keep_bekker():
    """An n-offset per level does not touch kc/b + kφ: only stiffness terms drop Eq. 7."""
    group = _sinkage_group(noise=0.01)
    fitted = _per_level("tool", ("n",)).fit(group, np.arange(len(group.tests)))
    assert "bekker" not in fitted.state
    assert list(fitted.result.param_names[:3]) == ["kc", "kphi", "n"]


def test_terms_redundant_among_themselves_are_refused_before_any_fit():
    """operator × tool's levels determine tool's: the two factor sets cannot be told apart."""
    group = _sinkage_group()
    nested = combine(
        [
            _per_level("tool"), _per_level("op_tool")
        ]
    )  # fmt: skip
    with pytest.raises(IdentifiabilityError, match="stiffness factors beside the base k"):
        nested.fit(group, np.arange(len(group.tests)))


def test_linear_trend_in_a_column_constant_on_the_tests_is_refused():
    group = _sinkage_group()
    rows = np.flatnonzero(group.tests["tool"].to_numpy() == "small")
    trend = SinkageExtension(
        "b_m (linear)", False, "k trend in b", bekker=False,
        terms=(Term(Features("b_m", "linear"), ("k", "n")),),
    )  # fmt: skip
    with pytest.raises(IdentifiabilityError, match="not determined on these 4 tests"):
        trend.fit(group, rows)


def _shear_group(one_sigma_per_level: bool) -> Group:
    """Janosi–Hanamoto tests (Eq. 13) at three normal stresses, labelled by ``load``."""
    j = np.linspace(0.0, 0.05, 40)
    c, tan_phi, k = 800.0, np.tan(np.radians(32.0)), 0.01
    rows, js, sig, ys, owner = [], [], [], [], []
    for i, sigma in enumerate((5e3, 10e3, 20e3)):
        for rep in range(3):
            label = f"L{i}" if one_sigma_per_level else f"R{rep}"
            tau = (c + sigma * tan_phi) * (1 - np.exp(-j / k))
            owner.append(np.full(j.size, len(rows)))
            rows.append({"test_id": f"{i}-{rep}", "load": label, "sigma_mean_Pa": sigma})
            js.append(j)
            sig.append(np.full(j.size, sigma))
            ys.append(tau)
    y = np.concatenate(ys)
    w = np.concatenate([np.full(t.size, 1 / t.max()) for t in ys])
    return Group(
        "shear",
        "s",
        pd.DataFrame(rows),
        {"j": np.concatenate(js), "sigma": np.concatenate(sig)},
        y,
        w,
        np.concatenate(owner),
    )


def test_c_and_tan_phi_factors_per_normal_stress_level_are_refused():
    """Factors on c and tan φ per level of a column that fixes σ: per level only c + σ·tan φ
    is measured (Eq. 12 at one σ), so the factors are not determined."""
    ext = ShearExtension(
        "load (levels)", False, "c, tan φ per load",
        terms=(Term(Features("load", "levels"), ("c", "tan_phi")),),
    )  # fmt: skip
    group = _shear_group(one_sigma_per_level=True)
    with pytest.raises(IdentifiabilityError, match="factors on c and tan φ beside the base"):
        ext.fit(group, np.arange(len(group.tests)))
    # The same extension over levels that each span every σ is fitted (and finds no effect).
    group = _shear_group(one_sigma_per_level=False)
    fitted = ext.fit(group, np.arange(len(group.tests)))
    assert fitted.result.converged
    assert np.allclose(fitted.result.values[3:], 0.0, atol=1e-5)


def test_library_fits_k_and_n_per_width_level_once():
    """With levels that fix the plate width, the generic 'k and n depend on tool' is the
    same model as 'k and n per tool' (Bernstein per plate): the library proposes it once;
    a stiffness-only generic extension is a different model and stays."""
    group = _sinkage_group(noise=0.01)
    rows = np.arange(len(group.tests))

    def names(responses):
        return [
            e.name for e in library(group, rows, "tool", (), numeric=False, responses=responses)
        ]

    both = names({"level", "shape"})
    assert "k and n per tool" in both and "tool (levels)" not in both
    assert "tool (levels)" in names({"level"})
