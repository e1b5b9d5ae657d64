"""The README's two set-up commands are the ones CI runs and the ones that work."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _bash_blocks(text: str) -> list[str]:
    return [b.strip() for b in re.findall(r"```bash\n(.*?)```", text, flags=re.S)]


def test_readme_has_exactly_two_setup_commands_and_ci_runs_the_test_one():
    readme = (ROOT / "README.md").read_text()
    setup = readme.split("## Set-up", 1)[1].split("\n## ", 1)[0]
    blocks = _bash_blocks(setup)
    assert len(blocks) == 2, blocks
    main_job, tests = blocks
    assert "pip install ." in main_job and "soilstats study" in main_job
    assert "pytest" in tests
    # .ci/run takes the test command from the README itself, by this pattern.
    ci = (ROOT / ".ci" / "run").read_text()
    pattern = re.search(r"grep -m1 -E '([^']+)' README.md", ci).group(1)
    found = [line for line in readme.splitlines() if re.search(pattern, line)]
    assert found and found[0] == tests


def test_ci_runs_in_a_fresh_clone_with_nothing_beside_it():
    ci = (ROOT / ".ci" / "run").read_text()
    assert "mktemp -d" in ci and "git clone" in ci and "test ! -e ../shared" in ci


def test_nothing_reads_outside_the_repository():
    """No module, test or benchmark refers to the development-only ../shared folder."""
    offenders = []
    for folder in ("soilstats", "tests", "benchmarks"):
        for path in (ROOT / folder).rglob("*.py"):
            if path == Path(__file__).resolve():
                continue
            text = path.read_text(encoding="utf-8")
            if re.search(r"\.\./shared|[\"']shared[\"']|/shared/", text):
                offenders.append(str(path.relative_to(ROOT)))
    assert not offenders, offenders
