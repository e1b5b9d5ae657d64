"""One record per soil model: a model of one's own, defined and registered in this file
alone, goes through identification, a posterior, discovery and a study by its name; an
unknown name is an error everywhere (docs/conventions.md, "The model record")."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pandas as pd
import pytest

import soilstats
from soilstats.errors import ModelError
from soilstats.models import Model, get_model, model_names, models_of_kind, register_model
from soilstats.models.base import ParamLabel, Positive
from soilstats.models.priors import FLAT, POSITIVE
from soilstats.models.starting_values import bernstein_start

# ------------------------------------------------------------------------- the toy model
# p = k·z^n·(1 + a·z): a power law whose stiffness grows (a > 0) or softens (a < 0) with depth.


def _zn(z, n):
    z = np.asarray(z, float)
    contact = z > 0
    lnz = np.log(np.where(contact, z, 1.0))
    return np.where(contact, np.exp(n * lnz), 0.0), lnz


def toy(z, k, n, a):
    zn, _ = _zn(z, n)
    return k * zn * (1.0 + a * np.asarray(z, float))


def toy_jac(z, k, n, a):
    z = np.asarray(z, float)
    zn, lnz = _zn(z, n)
    g = 1.0 + a * z
    return np.column_stack(np.broadcast_arrays(zn * g, k * zn * g * lnz, k * zn * z))


def toy_start(z, p):
    """Bernstein's start (Wong's estimate), with a = 0."""
    return np.append(bernstein_start(z, p), 0.0)


TOY = Model(
    name="toy-depth",
    equation="toy: p = k * z^n * (1 + a*z)",
    inputs=("z [m]",),
    output="p [Pa]",
    param_names=("k", "n", "a"),
    units=("N/m^(n+2)", "-", "1/m"),
    bounds=((0.0, np.inf), (0.0, 5.0), (-50.0, 50.0)),
    func=toy,
    jac=toy_jac,
    kind="sinkage",
    columns=("z_m",),
    start=toy_start,
    priors={"k": POSITIVE, "n": POSITIVE, "a": FLAT},
    support=(Positive("n"), Positive("k")),
    labels={"a": ParamLabel("a", r"$a$", "a", "1/m", "1/m", 1.0)},
)
TRUTH = {"k": 2.0e6, "n": 0.9, "a": 15.0}
STIFFER = 1.5  # k at the low velocity, relative
RADIUS = 0.05


@pytest.fixture(scope="module")
def toy_model():
    register_model(TOY)
    yield TOY
    soilstats.models.unregister_model(TOY.name)


@pytest.fixture(scope="module")
def campaign(tmp_path_factory, toy_model):
    """Eight tests at each of two velocities, p from the toy model with noise of 0.2 % of
    each test's largest pressure (the paper's weighted likelihood); the low velocity is
    stiffer (k × 1.5)."""
    folder = tmp_path_factory.mktemp("toy-campaign")
    rng = np.random.default_rng(1)
    tests, samples = [], []
    z = np.linspace(0.0005, 0.04, 60)
    for i in range(16):
        velocity = 0.001 if i < 8 else 0.01
        test_id = f"t{i:02d}"
        tests.append(
            {
                "test_id": test_id,
                "kind": "sinkage",
                "soil": "toy-soil",
                "shape": "circle",
                "radius_m": RADIUS,
                "velocity_m_s": velocity,
                "repetition": i % 8 + 1,
            }
        )
        k = TRUTH["k"] * (STIFFER if velocity == 0.001 else 1.0)
        p = toy(z, k, TRUTH["n"], TRUTH["a"])
        p = p + 0.002 * p.max() * rng.standard_normal(z.size)
        area = np.pi * RADIUS**2
        samples += [
            {"test_id": test_id, "z_m": zi, "force_N": pi * area}
            for zi, pi in zip(z, p, strict=True)
        ]
    pd.DataFrame(tests).to_csv(folder / "tests.csv", index=False)
    pd.DataFrame(samples).to_csv(folder / "sinkage.csv", index=False)
    return soilstats.load_campaign(folder)


# ------------------------------------------------------------------------ every layer


def test_the_record_is_registered_by_name(toy_model):
    assert get_model("toy-depth") is TOY
    assert TOY in models_of_kind("sinkage") and "toy-depth" not in model_names("shear")
    with pytest.raises(ModelError, match="registered already"):
        register_model(TOY.__class__(**{**TOY.__dict__}))  # an equal record, another object
    with pytest.raises(ModelError, match="paper's models"):
        soilstats.models.unregister_model("bekker")


def test_identify_recovers_the_planted_parameters(campaign):
    fit = soilstats.fit_sinkage(campaign, "toy-depth", velocity_m_s=0.01)
    assert fit.model_name == "toy-depth" and list(fit.params.index) == ["k", "n", "a"]
    assert fit.converged
    for name, truth in TRUTH.items():
        assert abs(fit.params[name] - truth) < 5 * fit.stderr[name], name
    np.testing.assert_allclose(fit.params.to_numpy(), list(TRUTH.values()), rtol=0.1)

    from soilstats.identification.conditions import fit_conditions

    table = fit_conditions(campaign, "sinkage", model="toy-depth").table()
    assert set(table["model"]) == {"toy-depth"} and set(table["condition"]) == {"0.001", "0.01"}


def test_a_posterior_uses_the_records_priors_and_support(campaign):
    from soilstats.bayes import sample_posterior
    from soilstats.bayes.support import check_support

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", soilstats.ConvergenceWarning)  # judged below
        post = sample_posterior(campaign, "toy-depth", draws=1500, seed=3, velocity_m_s=0.01)
    assert post.param_names == ("k", "n", "a")
    assert post.idata.posterior.attrs["priors"].startswith("k: flat on (0, inf)")
    draws = post.draws(1000, seed=0, allow_unconverged=True)
    for name, truth in TRUTH.items():
        lo, hi = np.quantile(draws[name], [0.001, 0.999])
        assert lo < truth < hi, (name, lo, hi)
    check = check_support(draws, (RADIUS, RADIUS), ["toy-depth"])
    assert set(check.reasons) == {"non-finite", "n <= 0", "k <= 0"} and check.passed


def test_discovery_extends_the_registered_model(campaign):
    result = soilstats.discover(campaign, model="toy-depth", max_leads=1)
    assert result.findings, result.summary()
    top = result.findings[0]
    assert top.cause == "velocity_m_s" and top.gain.real
    assert top.fitted.extension.name == "velocity" and top.fitted.extension.model is TOY
    # k ∝ v^θ: 1.5 times stiffer at a tenth of the velocity.
    theta = top.fitted.result.params["ln k-factor[ln(v/v_ref)]"]
    assert theta == pytest.approx(-np.log(STIFFER) / np.log(10), abs=0.01)
    assert [m.steps[0]["extension"] for m in result.models] == ["velocity"]


def test_a_study_fits_its_tables_with_the_registered_model(campaign, tmp_path):
    from soilstats.study import load_spec, run_study

    path = tmp_path / "toy-velocity.toml"
    path.write_text(
        'name = "toy-velocity"\ntype = "sinkage"\nfactor = "velocity_m_s"\n'
        'model = "toy-depth"\nz_ref_m = 0.02\n'
        '[[responses]]\nname = "log10_p_ref"\nlabel = "log10 p at 20 mm"\n'
    )
    result = run_study(load_spec(path), campaign)
    assert set(result.parameters["model"]) == {"toy-depth"}
    assert set(result.parameters["parameter"]) >= {"k", "n", "a"}
    effect = result.effects[result.effects["response"] == "log10_p_ref"].iloc[0]
    assert effect["significant"]


# --------------------------------------------------------------- unknown names: an error


def test_an_unknown_model_name_is_an_error_in_every_layer(campaign):
    from soilstats.bayes import sample_population, sample_posterior
    from soilstats.identification.conditions import fit_conditions
    from soilstats.models.starting_values import sinkage_start

    known = r"unknown model 'bekkr'; choose one of \['(bekker|janosi)', "
    calls = [
        lambda: get_model("bekkr"),
        lambda: soilstats.fit_sinkage(campaign, "bekkr"),
        lambda: soilstats.fit_shear(campaign, "bekkr"),
        lambda: fit_conditions(campaign, "sinkage", model="bekkr"),
        lambda: sinkage_start("bekkr", None, np.ones(3), np.ones(3)),
        lambda: sample_posterior(campaign, "bekkr"),
        lambda: sample_population(campaign, "bekkr"),
        lambda: soilstats.discover(campaign, model="bekkr"),
    ]
    for call in calls:
        with pytest.raises(ModelError, match=known):
            call()
    # A model of the wrong kind names the right ones (never a silent default).
    with pytest.raises(ModelError, match=r"for shear tests choose one of \['janosi'"):
        soilstats.fit_shear(campaign, "bekker")
    with pytest.raises(ModelError, match=r"for sinkage tests choose one of \['bekker'"):
        sinkage_start("janosi", None, np.ones(3), np.ones(3))
    # A record discovery cannot fit is refused before any fit, saying why.
    odd = dataclasses.replace(TOY, name="toy-odd", columns=("sigma_Pa",))
    with pytest.raises(ModelError, match="discovery has the inputs"):
        soilstats.discover(campaign, model=odd)


def test_an_unknown_model_name_is_exit_2_on_the_command_line(tmp_path, capsys):
    from soilstats.cli.main import main

    def run(*args) -> tuple[int, str]:
        code = main(list(args))
        return code, capsys.readouterr().err

    code, err = run("identify", "--data", "grc1-oravec2009", "--model", "bekkr")
    assert code == 2 and "'bekker', 'bernstein', 'reece'" in err
    out = str(tmp_path / "out")
    code, err = run("posterior", "--soil", "GRC-1", "--model", "bekkr", "--out", out)
    assert code == 2 and "unknown model 'bekkr'" in err
    assert "'bekker', 'bernstein', 'reece', 'janosi', 'mohr-coulomb'" in err
    code, err = run("posterior", "--soil", "GRC-1", "--model", "bekker+bernstein", "--out", out)
    assert code == 2 and "one sinkage and one shear model" in err
    code, err = run("posterior", "--soil", "GRC-1", "--model", "shear-curve", "--out", out)
    assert code == 2 and "has no posterior" in err
    spec = tmp_path / "bad.toml"
    spec.write_text(
        'name = "bad"\ntype = "sinkage"\nfactor = "velocity_m_s"\nmodel = "bekkr"\n'
        '[[responses]]\nname = "n"\nlabel = "n"\n'
    )
    code, err = run("study", str(spec), "--out", str(tmp_path / "study"))
    assert code == 2 and "'bekker', 'bernstein', 'reece'" in err
