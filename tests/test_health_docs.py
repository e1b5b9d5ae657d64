"""Every fit health code is documented: what, why it matters, what to do.

The codes are read from the source (``HealthFlag("<code>"`` literals under soilstats/fitting
and soilstats/identification, documented in docs/identification.md; under soilstats/bayes, a
posterior's convergence codes, in docs/posterior.md), so a new code without an entry fails
here. An entry is a
``### `code` `` heading whose section holds **What.**, **Why it matters.** and **What to
do.**, or a table row whose header has the columns what / why it matters / what to do, each
cell filled.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
DOCS = ROOT / "docs"
SOURCES = ("soilstats/fitting", "soilstats/identification")
POSTERIOR_SOURCES = ("soilstats/bayes",)
PARTS = ("**What.**", "**Why it matters.**", "**What to do.**")
COLUMNS = ("what", "why it matters", "what to do")

_CALL = re.compile(r"HealthFlag\(\s*([^\s,)]+)")
_LITERAL = re.compile(r'"([a-z0-9-]+)"')

#: ``HealthFlag(<variable>, …)`` calls, by file and variable: their codes come from a list
#: checked below. A new call of this kind fails the scan until it is listed here.
VARIABLE_CODES = {("soilstats/identification/result.py", "code")}


def emitted_codes(sources: tuple[str, ...] = SOURCES) -> set[str]:
    """Codes of ``HealthFlag("<code>", …)`` calls; fails on an unlisted non-literal code."""
    codes, unlisted = set(), []
    for folder in sources:
        for path in sorted((ROOT / folder).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            for arg in _CALL.findall(path.read_text(encoding="utf-8")):
                literal = _LITERAL.fullmatch(arg)
                if literal:
                    codes.add(literal.group(1))
                elif (rel, arg) not in VARIABLE_CODES:
                    unlisted.append(f"{rel}: HealthFlag({arg}, …)")
    assert not unlisted, f"health codes built from variables, not checked: {unlisted}"
    return codes


def _cells(line: str) -> list[str]:
    return [c.strip() for c in re.split(r"(?<!\\)\|", line.strip().strip("|"))]


def entries(text: str, code: str) -> list[tuple[str, bool]]:
    """(where, complete) for each heading or table row of ``code`` in a markdown text."""
    lines = text.splitlines()
    found = []
    for i, line in enumerate(lines):
        if re.fullmatch(rf"#+ `{re.escape(code)}`(\s.*)?", line.strip()):
            end = next(
                (j for j in range(i + 1, len(lines)) if lines[j].startswith("#")), len(lines)
            )
            section = "\n".join(lines[i:end])
            found.append((line.strip(), all(part in section for part in PARTS)))
        elif line.startswith("|") and _cells(line)[0] == f"`{code}`":
            top = i
            while top > 0 and lines[top - 1].startswith("|"):
                top -= 1
            header = [c.lower() for c in _cells(lines[top])]
            row = _cells(line)
            ok = all(col in header for col in COLUMNS) and all(
                header.index(col) < len(row) and row[header.index(col)] for col in COLUMNS
            )
            found.append((f"table row of {code}", ok))
    return found


def _identification_md() -> str:
    return (DOCS / "identification.md").read_text(encoding="utf-8")


def test_the_scan_finds_the_known_codes():
    # A guard on the regex: these are emitted today.
    known = {
        "not-converged",
        "outside-bounds",
        "high-correlation",
        "undetermined",
        "rank-deficient",
        "excluded-tests",
        "lack-of-fit",
        "plate-exponents",
        "aggregation-bias",
        "test-scatter",
        "sign-unstable",
        "bootstrap-unstable",
    }
    assert known <= emitted_codes()


@pytest.mark.parametrize("code", sorted(emitted_codes()))
def test_every_fit_code_has_what_why_and_what_to_do(code):
    found = entries(_identification_md(), code)
    assert found, f"{code}: no heading or table row in docs/identification.md"
    assert all(ok for _, ok in found), f"{code}: an entry lacks What / Why it matters / What to do"


def test_the_scan_finds_every_posterior_code():
    # A guard on the scan of soilstats/bayes: every code of CONVERGENCE_CODES is emitted as a
    # literal there, and nothing else is (a new code must join the tuple and the docs).
    from soilstats.bayes.result import CONVERGENCE_CODES

    assert emitted_codes(POSTERIOR_SOURCES) == set(CONVERGENCE_CODES)


@pytest.mark.parametrize("code", sorted(emitted_codes(POSTERIOR_SOURCES)))
def test_every_posterior_code_has_what_why_and_what_to_do(code):
    found = entries((DOCS / "posterior.md").read_text(encoding="utf-8"), code)
    assert found, f"{code}: no heading or table row in docs/posterior.md"
    assert all(ok for _, ok in found), f"{code}: an entry lacks What / Why it matters / What to do"


def test_the_data_quality_codes_a_fit_carries_are_listed_and_documented():
    from soilstats.identification.result import _FIT_CODES

    text = _identification_md()
    listed = text.split("## Health flags", 1)[1].split("\n## ", 1)[0]
    quality = (DOCS / "quality.md").read_text(encoding="utf-8")
    for code in _FIT_CODES:
        assert f"`{code}`" in listed, f"{code}: not in docs/identification.md, Health flags"
        found = entries(quality, code)
        assert found and all(ok for _, ok in found), f"{code}: docs/quality.md"


def test_discovery_red_flags_say_what_to_do():
    source = (ROOT / "soilstats/discovery/flags.py").read_text(encoding="utf-8")
    codes = set(re.findall(r'code = f?"([a-z-]+)', source))
    codes |= set(re.findall(r'"code": "([a-z-]+)"', source))
    assert codes == {"kc-kphi-collinear", "implausible-", "not-converged"}
    text = (DOCS / "discover.md").read_text(encoding="utf-8")
    for code in codes:
        documented = "implausible-<param>" if code == "implausible-" else code
        found = entries(text, documented)
        assert found and all(ok for _, ok in found), f"{code}: docs/discover.md"
