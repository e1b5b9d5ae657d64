"""The campaign digest of every output's provenance keeps its definition (the bytes it
hashes), so that reports written before and after a change of implementation name the same
data with the same digest."""

from __future__ import annotations

import hashlib

import numpy as np
import pandas as pd

import soilstats
from soilstats.campaign.digest import campaign_sha256
from soilstats.campaign.schema import DERIVED_COLUMNS, FILES


def _definition(campaign) -> str:
    """campaign_sha256 as its docstring defines it, cell by cell."""
    digest = hashlib.sha256()
    for stem in FILES:
        table = getattr(campaign, stem)
        raw = [c for c in table.columns if c not in DERIVED_COLUMNS[stem]]
        digest.update(f"\x1e{stem}:{len(table)}".encode())
        for column in raw:
            values = table[column]
            digest.update(f"\x1d{column}".encode())
            if pd.api.types.is_numeric_dtype(values) and not pd.api.types.is_bool_dtype(values):
                digest.update(values.to_numpy(dtype="<f8", na_value=np.nan).tobytes())
            else:
                cells = ("\x00" if pd.isna(v) else str(v) for v in values)
                digest.update("\x1f".join(cells).encode("utf-8"))
    return digest.hexdigest()


def test_digest_is_the_defined_one_with_missing_text_and_covariates(tmp_path):
    campaign = soilstats.load_campaign("cullinan-sand")  # text covariates, missing cells
    assert campaign.tests["void_ratio"].isna().any()
    assert campaign_sha256(campaign) == _definition(campaign)
    tests = campaign.tests.drop(columns=list(DERIVED_COLUMNS["tests"]))
    sinkage = campaign.sinkage.drop(columns="pressure_Pa")
    sinkage["note"] = np.where(np.arange(len(sinkage)) % 7 == 0, "", "ok")  # missing text
    sinkage.loc[3, "note"] = "\x00"  # a cell that reads like the missing marker
    noted = soilstats.Campaign.from_frames(tests, sinkage)
    assert noted.sinkage["note"].isna().any()
    assert campaign_sha256(noted) == _definition(noted)
    # an object column (a campaign assembled by hand) is hashed by the same definition
    mixed = noted.sinkage.assign(note=noted.sinkage["note"].astype(object))
    by_hand = soilstats.Campaign(noted.tests, mixed, noted.shear)
    assert campaign_sha256(by_hand) == _definition(by_hand) == campaign_sha256(noted)


def test_digest_of_shear_campaign_is_the_defined_one():
    campaign = soilstats.load_campaign("simulated-paper").select(kind="shear")
    assert len(campaign.shear) and campaign_sha256(campaign) == _definition(campaign)


def test_every_command_names_the_data_it_was_given_not_the_screened_copy(tmp_path, capsys):
    """check, identify and discover on one folder record one campaign_sha256: that of the
    records as loaded (screening's removals and re-zeroing are the commands' processing,
    recorded by their command line).  A library call names the campaign it was given."""
    import json

    from soilstats.cli.main import main
    from soilstats.discovery import discover
    from soilstats.quality import screen
    from soilstats.simulation import simulate

    spec = {
        "name": "provenance",
        "soils": {"sand": {"kc": 900.0, "kphi": 1.5e6, "n": 1.1}},
        "series": [
            {
                "name": "plates",
                "kind": "sinkage",
                "soils": ["sand"],
                "plates": [{"shape": "circle", "radius_m": b} for b in (0.025, 0.05)],
                "repetitions": 4,
                "points": 120,
                "sinkage_m": 0.03,
            }
        ],
    }
    clean = simulate(spec, seed=2).campaign
    tests = clean.tests.drop(columns=list(DERIVED_COLUMNS["tests"]))
    sinkage = clean.sinkage.drop(columns=list(DERIVED_COLUMNS["sinkage"])).reset_index(drop=True)
    sinkage.loc[60, "z_m"] *= 10.0  # a spike that screening takes out
    spiked = soilstats.Campaign.from_frames(tests, sinkage)
    assert campaign_sha256(screen(spiked).campaign) != campaign_sha256(spiked)
    folder = spiked.save(tmp_path / "spiked")
    digests = {}
    for command in ("check", "identify", "discover"):
        assert main([command, "--data", str(folder), "--json", "--progress", "off"]) == 0
        digests[command] = json.loads(capsys.readouterr().out)["provenance"]["campaign_sha256"]
    assert set(digests.values()) == {campaign_sha256(spiked)}, digests
    assert discover(spiked).provenance.campaign_sha256 == campaign_sha256(spiked)
