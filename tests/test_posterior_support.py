"""Physical support of draws, prior parsing and the simulator record (no sampling)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from soilstats.bayes import simulator_parameters, simulator_record
from soilstats.bayes.pooling import pooling_warnings
from soilstats.bayes.priors import Normal, Uniform, parse_prior, priors_from_toml
from soilstats.bayes.support import MAX_OUTSIDE, check_support, negative_modulus_width
from soilstats.campaign import load_campaign


def test_each_rule_rejects_exactly_its_draws():
    draws = pd.DataFrame(
        {
            # kc/b + kphi at b = 0.01 and 0.1: row 2 is negative at b = 0.01 only.
            "kc": [1e3, -1e3, -2e4, 1e3, 1e3, np.inf],
            "kphi": [1e5, 1e6, 1e6, 1e5, 1e5, 1e5],
            "n": [1.0, 1.0, 1.0, -0.1, 1.0, 1.0],
            "phi": [30.0, 30.0, 30.0, 30.0, 95.0, 30.0],
        }
    )
    check = check_support(draws, (0.01, 0.1))
    assert check.inside.tolist() == [True, True, False, False, False, False]
    assert check.reasons["kc/b + kphi <= 0"] == 1 and check.reasons["n <= 0"] == 1
    assert check.reasons["phi outside (0, 90) deg"] == 1 and check.reasons["non-finite"] == 1
    assert not check.passed and check.share_outside == pytest.approx(4 / 6)
    # The same draws at wide contacts only: row 2's modulus is positive there.
    assert check_support(draws.iloc[:3], (0.05, 0.1)).inside.all()


def test_passes_up_to_the_stated_share():
    n = np.ones(1000)
    n[: int(MAX_OUTSIDE * 1000)] = -1
    assert check_support(pd.DataFrame({"k": 1.0, "n": n}), (0.05, 0.05)).passed
    n[int(MAX_OUTSIDE * 1000)] = -1
    assert not check_support(pd.DataFrame({"k": 1.0, "n": n}), (0.05, 0.05)).passed


def test_negative_modulus_width_is_minus_kc_over_kphi():
    draws = pd.DataFrame({"kc": [-2e3] * 50 + [1e3] * 50, "kphi": [1e6] * 100})
    assert negative_modulus_width(draws, 0.99) == pytest.approx(2e-3)  # 2 mm
    assert negative_modulus_width(draws.assign(kc=1e3)) is None
    record = simulator_record(draws.assign(n=1.0, c=0.0, phi=30.0, K=0.01))
    assert record["negative_modulus_below_m"] == pytest.approx(2e-3)
    assert "turns negative" in record["notes"][0]


def test_simulator_columns_carry_the_stated_inputs():
    draws = pd.DataFrame({"kc": [1e3], "kphi": [1e6], "n": [1.0], "c": [0], "phi": [30], "K": [1]})
    table = simulator_parameters(draws, damping_R=1e4)
    assert table.loc[0, "elastic_K"] == 4e7 and table.loc[0, "damping_R"] == 1e4
    with pytest.raises(ValueError, match="elastic_K must be positive"):
        simulator_parameters(draws, elastic_K=-1)


def test_prior_text_forms(tmp_path):
    assert parse_prior("0.2:2") == Uniform(0.2, 2.0)
    assert parse_prior("normal:1:0.3:0:inf") == Normal(lower=0, upper=np.inf, mu=1, sd=0.3)
    for bad in ("2:0.2", "normal:1", "gauss:1:2", "x"):
        with pytest.raises(ValueError, match="cannot read the prior"):
            parse_prior(bad)
    path = tmp_path / "priors.toml"
    path.write_text('[bekker]\nn = "0.5:1.5"\n[janosi]\nK = "normal:0.01:0.005:0:inf"\n')
    assert priors_from_toml(path, "bekker") == {"n": Uniform(0.5, 1.5)}
    assert priors_from_toml(path, "bernstein") == {}
    path.write_text('[bekker]\nn = "oops"\n')
    with pytest.raises(ValueError, match=r"priors.toml, \[bekker\]"):
        priors_from_toml(path, "bekker")


def test_pooling_conditions_is_said_for_the_kinds_pooled_only():
    campaign = load_campaign("simulated-paper")
    said = pooling_warnings(campaign, "soil01", ["bekker"])
    assert any("velocity_m_s" in w for w in said)
    # A sinkage-only posterior uses no shear test: it said six sentences about them (#45).
    assert not [w for w in said if "shear" in w]
    said = pooling_warnings(campaign, "soil01", ["bekker", "janosi"])
    # shear rings of two sizes (tool04, tool07) and three grouser counts are pooled too
    assert any("shear posterior pools 2 values of tool" in w for w in said)
    assert any("shear posterior pools 3 values of grousers" in w for w in said)
    assert not [w for w in pooling_warnings(campaign, "soil01", ["janosi"]) if "sinkage" in w]
    one = campaign.select(velocity_m_s=4.8e-3, preparation="1")
    assert not [w for w in pooling_warnings(one, "soil01", ["bekker"]) if "sinkage" in w]


def test_each_prior_reaches_its_model_or_is_refused(tmp_path):
    from soilstats.bayes.prior_options import priors_by_model, split_prior_items

    path = tmp_path / "priors.toml"
    path.write_text('[bekker]\nn = "0.5:1.5"\n[janosi]\nK = "0:0.1"\n')
    chosen = priors_by_model(["n=0.6:1.2", "phi=20:40"], path, ["bekker", "janosi"])
    assert chosen["bekker"] == {"n": Uniform(0.6, 1.2)}  # the command line wins
    assert chosen["janosi"] == {"K": Uniform(0.0, 0.1), "phi": Uniform(20.0, 40.0)}
    # kc is a parameter of bekker, not of janosi: a [janosi] kc must not vanish silently.
    path.write_text('[janosi]\nkc = "0:1"\n')
    with pytest.raises(ValueError, match=r"\[janosi\]: \['kc'\]"):
        priors_by_model([], path, ["bekker", "janosi"])
    with pytest.raises(ValueError, match="--prior names"):
        priors_by_model(["nn=0:1"], None, ["bekker"])
    # With a simulator export, c/phi/K of a sinkage-only run are user priors, not refused.
    items = ["n=0.6:1.2", "c=uniform:0:2000"]
    posterior, stated = split_prior_items(items, ["bekker"], "chrono-scm")
    assert posterior == ["n=0.6:1.2"] and set(stated) == {"c"}
    assert priors_by_model(items, None, ["bekker"], "chrono-scm") == {
        "bekker": {"n": Uniform(0.6, 1.2)}
    }
