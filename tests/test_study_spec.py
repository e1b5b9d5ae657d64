"""Study specifications: the shipped ones load; malformed ones fail with a clear message."""

from __future__ import annotations

import pytest

from soilstats.study import SpecError, available_studies, load_spec
from soilstats.study.spec import studies_dir

VALID = """
name = "mine"
type = "shear"
factor = "grousers"
model = "mohr-coulomb"
responses = ["phi"]
"""


def test_seven_studies_are_shipped_and_valid():
    assert available_studies() == [
        "preparation",
        "velocity",
        "tool-shape",
        "shear-ring",
        "grousers",
        "grouser-height",
        "shear-velocity",
    ]
    for name in available_studies():
        spec = load_spec(name)
        assert spec.name == name and spec.responses and spec.paper
    assert (studies_dir() / "velocity.toml").is_file()


def test_a_user_study_is_a_file(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(VALID)
    spec = load_spec(path)
    assert (spec.name, spec.kind, spec.responses[0].name) == ("mine", "shear", "phi")


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ("typo_key = 1\n", "unknown key"),
        ("alpha = 2\n", "must lie in (0, 1)"),
        ('figures = ["pie"]\n', "is not one of"),
    ],
)
def test_malformed_specs_name_the_key(tmp_path, change, message):
    path = tmp_path / "bad.toml"
    path.write_text(change + VALID)
    with pytest.raises(SpecError, match=r"bad\.toml") as err:
        load_spec(path)
    assert message in str(err.value)


def test_unknown_response_and_missing_factor(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(VALID.replace('["phi"]', '["kc"]'))
    with pytest.raises(SpecError, match="'kc' is not one of"):
        load_spec(path)
    path.write_text(VALID.replace('factor = "grousers"\n', ""))
    with pytest.raises(SpecError, match="'factor': is required"):
        load_spec(path)


def test_a_window_in_the_spec_reaches_every_fit(tmp_path):
    from soilstats.campaign import load_campaign
    from soilstats.study import run_study

    text = (studies_dir() / "velocity.toml").read_text()
    path = tmp_path / "windowed.toml"
    path.write_text(
        text.replace('name = "velocity"', 'name = "windowed"')
        + '\n[window]\nz_max = ["radius_m=0.05:0.027"]\n'
    )
    spec = load_spec(path)
    assert spec.window.describe() == "radius_m = 0.05: z <= 0.027 m"
    campaign = load_campaign("simulated-paper").select(soil="soil01")
    result = run_study(spec, campaign)
    assert any("radius_m = 0.05: z <= 0.027 m" in note for note in result.notes)
    plain = run_study(load_spec("velocity"), campaign)
    # The 50 mm plate's pooled fits see less data: their parameters move, the others' do not.
    assert not result.parameters.equals(plain.parameters)
    path.write_text(text + '\n[window]\nz_max = ["radius_m=0.05"]\n')
    with pytest.raises(SpecError, match="window"):
        load_spec(path)


def test_a_reference_level_absent_from_the_data_is_an_error(tmp_path):
    """A reference the factor never takes used to give an empty reference-pairs table."""
    from soilstats.campaign import load_campaign
    from soilstats.errors import StudyDataError
    from soilstats.study import run_study

    text = (studies_dir() / "tool-shape.toml").read_text()
    path = tmp_path / "typo.toml"
    path.write_text(text.replace('reference = "tool02"', 'reference = "tool2"'))
    campaign = load_campaign("simulated-paper").select(soil="soil01")
    with pytest.raises(StudyDataError, match=r"reference = 'tool2' is not a tool value.*tool02"):
        run_study(load_spec(path), campaign)
