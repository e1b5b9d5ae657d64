"""The typeset PDF reports: complete (everything in the JSON is in the PDF), inside the page,
numbered, one page size, embedded fonts, and renderable — for every report type."""

from __future__ import annotations

import json
import os
import re
import shutil

import pdfplumber
import pytest
from pypdf import PdfReader

from soilstats.cli.main import main
from soilstats.report.document import Document, esc, render_page, strong
from soilstats.report.labels import column_label, natural_sorted

A4 = (595.28, 841.89)  # points


def _squeeze(text: str) -> str:
    """Text with all whitespace and soft breaks removed: line breaks fall anywhere in a PDF."""
    return re.sub(r"[\s\u200b\u00ad]+", "", text)


def pdf_text(path) -> str:
    return _squeeze("".join(page.extract_text() for page in PdfReader(path).pages))


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    """Every report type, written by the CLI with its JSON: {name: (pdf, json document)}."""
    out = tmp_path_factory.mktemp("reports")
    runs = {
        "study": (["study", "preparation", "--data", "cullinan-sand"], "preparation"),
        "discover": (["discover", "--data", "grc1-oravec2009"], "discover"),
        "check": (["check", "--data", "grc1-oravec2009"], "check"),
        "identify": (["identify", "--data", "grc1-oravec2009"], "identify"),
        "posterior": (
            [
                "posterior",
                "--data",
                "grc1-oravec2009",
                "--soil",
                "GRC-1",
                "--model",
                "bernstein",
                "--select",
                "sinkage:b_m=0.095",
            ],
            "report",
        ),
    }
    made = {}
    for name, (argv, stem) in runs.items():
        folder = out / name
        assert main([*argv, "--out", str(folder), "--progress", "off"]) == 0, name
        record = "posterior.json" if name == "posterior" else f"{stem}.json"
        made[name] = (folder / f"{stem}.pdf", json.loads((folder / record).read_text()))
    return made


def test_page_one_answers_question_data_and_conclusion(reports):
    for name, (pdf, _) in reports.items():
        first = _squeeze(PdfReader(pdf).pages[0].extract_text())
        for heading in ("Question", "Data", "Conclusion"):
            assert heading in first, (name, heading)
        assert "measureddata" in first, name  # bundled real campaigns, said plainly


def test_every_page_is_numbered_a4_and_inside_its_box(reports):
    for name, (pdf, _) in reports.items():
        with pdfplumber.open(pdf) as doc:
            n = len(doc.pages)
            for page in doc.pages:
                assert (round(page.width, 1), round(page.height, 1)) == (
                    round(A4[0], 1),
                    round(A4[1], 1),
                ), (name, page.page_number)
                outside = [
                    c["text"]
                    for c in page.chars
                    if c["x0"] < 0
                    or c["x1"] > page.width
                    or c["top"] < 0
                    or c["bottom"] > page.height
                ]
                assert not outside, (name, page.page_number, "".join(outside)[:80])
                text = _squeeze(page.extract_text())
                assert f"Page{page.page_number}of{n}" in text, (name, page.page_number)


def test_fonts_are_embedded_and_never_type3(reports):
    for name, (pdf, _) in reports.items():
        for number, page in enumerate(PdfReader(pdf).pages, 1):
            fonts = page["/Resources"].get("/Font", {})
            for key, ref in fonts.items():
                font = ref.get_object()
                assert font["/Subtype"] != "/Type3", (name, number, key)
                descendants = [d.get_object() for d in font.get("/DescendantFonts", [])]
                for f in descendants or [font]:
                    descriptor = f["/FontDescriptor"].get_object()
                    assert any(
                        k in descriptor for k in ("/FontFile", "/FontFile2", "/FontFile3")
                    ), (
                        name,
                        number,
                        f.get("/BaseFont"),
                    )


def test_last_page_carries_the_provenance(reports):
    for name, (pdf, doc) in reports.items():
        last = _squeeze(PdfReader(pdf).pages[-1].extract_text())
        prov = doc["provenance"]
        assert "Provenance" in last, name
        assert prov["campaign_sha256"] in last and _squeeze(prov["command"]) in last, name
        assert PdfReader(pdf).metadata["/Subject"].endswith(prov["campaign_sha256"]), name


def test_discover_pdf_holds_every_finding_flag_note_and_record(reports):
    pdf, doc = reports["discover"]
    text = pdf_text(pdf)
    expected = []
    for f in doc["findings"]:
        expected += [f["cause"], f["extension"], *f["caveats"], *f["confounded_with"]]
        expected += [t["extension"] for t in f["tried"]]
    expected += [fl["message"] for fl in doc["flags"]]
    expected += [c["text"] for c in doc["confounded"]]
    expected += [c["reason"] for c in doc["columns"]] + [c["column"] for c in doc["columns"]]
    expected += [a["reason"] for a in doc["artefacts"]]
    expected += [
        s
        for p in doc["power"]
        for s in (p["candidate"], *(v["statement"] for v in p["responses"].values()))
    ]
    expected += [t["test_id"] for t in doc["quality"]["tests"]]
    expected += doc["notes"] + doc["model"]["extensions"]
    missing = [e for e in expected if e and _squeeze(str(e)) not in text]
    assert not missing, missing[:5]
    assert doc["findings"], "GRC-1 has a finding to check"


def test_check_pdf_holds_every_flag_of_every_test(reports):
    pdf, doc = reports["check"]
    text = pdf_text(pdf)
    expected = [fl["message"] for t in doc["tests"] for fl in t["flags"]]
    expected += [t["test_id"] for t in doc["tests"] if t["flags"]]
    expected += [c["action"] for c in doc["codes"].values()]
    missing = [e for e in expected if _squeeze(e) not in text]
    assert not missing, missing[:3]
    assert len(expected) > 20


def test_identify_pdf_holds_every_health_flag_and_note(reports):
    pdf, doc = reports["identify"]
    text = pdf_text(pdf)
    expected = [h["message"] for f in doc["fits"] for h in f["health"]]
    expected += [n for f in doc["fits"] for n in f["notes"]]
    missing = [e for e in expected if _squeeze(e) not in text]
    assert not missing, missing[:3]
    assert expected


def test_posterior_pdf_holds_every_check_prior_and_warning(reports):
    pdf, doc = reports["posterior"]
    text = pdf_text(pdf)
    expected = [*doc["priors"].values(), *doc["warnings"], *doc["pooling_warnings"]]
    expected += [*doc["failures"], *doc["selection"], str(doc["draws_written"])]
    expected += list(doc["support"]["reasons"])
    missing = [e for e in expected if _squeeze(e) not in text]
    assert not missing, missing[:3]
    assert "sinkagez(mm)" in text or "Measuredpressure" in text  # the predictive check


def test_study_pdf_holds_every_verdict_criterion_and_note(reports):
    pdf, doc = reports["study"]
    text = pdf_text(pdf)
    expected = [e["verdict"] for e in doc["effects"]] + list(doc["notes"])
    for c in doc["criteria"]:
        expected += [c["crit1_reason"], c["crit2_reason"], c["crit3_reason"]]
    expected.append(doc["best_method"]["reason"])
    missing = [e for e in expected if _squeeze(e) not in text]
    assert not missing, missing[:3]
    assert "preparation_m" not in text and "log10_p_ref" not in text  # human labels only


def test_pdftoppm_renders_page_one(reports, tmp_path):
    """Fails (in CI, where pdftoppm is installed) if a report cannot be rendered."""
    if shutil.which("pdftoppm") is None:
        if os.environ.get("SOILSTATS_REQUIRE_PDFTOPPM"):
            pytest.fail("pdftoppm (Debian: poppler-utils) is required here")
        pytest.skip("pdftoppm (Debian: poppler-utils) not installed")
    from matplotlib.image import imread

    for name, (pdf, _) in reports.items():
        image = imread(render_page(pdf, tmp_path / name, dpi=40))
        assert image.shape[0] > 400 and image.shape[1] > 300, name
        ink = (image[..., :3].mean(axis=2) < 0.5).mean()
        assert 0.002 < ink < 0.5, (name, ink)  # text on a white page


def test_text_from_data_is_never_markup(tmp_path):
    """Characters Typst reads as markup ($ # [ ] * _ \\ @ <) print as themselves."""
    nasty = 'x = $a$ #import "y" [b] *c* _d_ \\e @f <g> "h"'
    doc = Document(nasty)
    doc.paragraph(nasty, " ", strong(nasty))
    doc.bullets([nasty])
    import pandas as pd

    doc.table(pd.DataFrame({"col $#": [nasty]}), caption=nasty)
    path = tmp_path / "x.pdf"
    assert doc.render(path) == 1
    text = pdf_text(path)
    assert text.count(_squeeze(nasty)) >= 4
    assert esc("a").text == '#"a"'


def test_long_tables_continue_on_the_next_page_with_their_header(tmp_path):
    import pandas as pd

    doc = Document("Long")
    frame = pd.DataFrame({"test": [f"test-{i}" for i in range(200)], "value": range(200)})
    doc.table(frame, caption="Two hundred rows.")
    path = tmp_path / "long.pdf"
    pages = doc.render(path)
    assert pages >= 4
    text = pdf_text(path)
    assert all(f"test-{i}" in text for i in (0, 99, 199))
    for page in PdfReader(path).pages[1:]:
        assert "testvalue" in _squeeze(page.extract_text())  # the header repeats


def test_levels_sort_naturally_and_labels_are_human():
    assert natural_sorted(["10", "2", "1", "11"]) == ["1", "2", "10", "11"]
    assert natural_sorted(["soil10", "soil2", "soil01"]) == ["soil01", "soil2", "soil10"]
    assert natural_sorted([0.0048, 0.00048, 0.0024]) == [0.00048, 0.0024, 0.0048]
    assert column_label("velocity_m_s") == "penetration velocity (m/s)"
    assert column_label("grouser_height_m") == "grouser height (m)"
    assert column_label("torque_Nm") == "torque (N·m)"


def test_reports_are_byte_identical_between_runs(tmp_path, monkeypatch):
    paths = []
    for run in ("a", "b"):  # the same command line (it is in the provenance) in two folders
        (tmp_path / run).mkdir()
        monkeypatch.chdir(tmp_path / run)
        assert main(["discover", "--data", "cullinan-sand", "--out", "rep"]) == 0
        paths.append(tmp_path / run / "rep" / "discover.pdf")
    assert paths[0].read_bytes() == paths[1].read_bytes()


def test_no_text_below_8_pt_and_no_overlapping_text(reports):
    """Issue #47 item 5: every report's PDF read by its text boxes — none below 8 pt, none
    overlapping another (tests/pdf_text.py)."""
    from pdf_text import small_and_overlapping

    for name, (pdf, _) in reports.items():
        assert small_and_overlapping(pdf) == [], name


def test_a_studys_curve_caption_names_the_campaigns_plate_not_the_papers(reports):
    """Issue #47 item 5: the preparation study's curves figure said "plate radius (m) = 0.05"
    (the paper's plate, from the spec) under the Cullinan curves, all drawn on 0.075694 m
    plates (the spec's filter matches no test there, so none is applied)."""
    pdf, _ = reports["study"]
    text = pdf_text(pdf)
    caption = text[text.index("Pressure–sinkagecurvesbypreparation") :][:120]
    assert "plateradius(m)=0.075694" in caption and "=0.05)" not in caption, caption


def test_no_python_text_in_any_report(reports):
    """Issue #47 item 5: no dict or list repr, numpy scalar, nan, Python None or API pointer
    (``to_dict()['excluded']``, ``result.tests``) printed in any report (tests/pdf_text.py)."""
    from pdf_text import python_text

    for name, (pdf, _) in reports.items():
        assert python_text(pdf) == [], name


def test_a_studys_methods_describe_the_campaign_before_the_papers_design(reports):
    """Issue #47 item 5: the Cullinan preparation study has 13 tests of 5 methods, not the
    paper's thirteen methods; the Methods say the campaign's design first, from its tests."""
    pdf, _ = reports["study"]
    text = pdf_text(pdf)
    methods = text[text.index("4Methods") + 1 :]
    assert methods.startswith("MethodsThiscampaign:13testsofcullinan-sandanalysed"), methods[:80]
    assert "preparation:1(6tests),2(4tests),3(1test),4(1test),5(1test)" in methods
    assert methods.index("Thiscampaign") < methods.index("Thepaper'sdesign,forcomparison")
