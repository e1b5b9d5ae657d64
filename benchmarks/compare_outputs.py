"""Side-by-side proof that a refactor changed no result: capture outputs, then compare bytes.

    python benchmarks/compare_outputs.py capture /tmp/refactor-baseline   # before the change
    python benchmarks/compare_outputs.py capture /tmp/refactor-after      # after it
    python benchmarks/compare_outputs.py compare /tmp/refactor-baseline /tmp/refactor-after
    python benchmarks/compare_outputs.py --smoke    # that it runs (tests/test_benchmarks.py)

``capture`` writes into DIR (created; must not exist yet):

- ``fits.json``: every NIST StRD nonlinear problem from both starts through ``identify``
  (``tests/reference``; a start that raises ConvergenceError is recorded with its message and
  the result it carries), plus the soil models through each of ``identify``'s paths (power
  law, separable start, the model's closures, a bare function, weights with zeros) and the
  error messages of invalid input.  For each fit: the FitResult's numbers (estimates, σ,
  covariance, residuals, ε, cond, counts, message, flags) and the raw LMOutcome of the
  optimiser (stopping reason, evaluation counts, the Gram matrix and the decompositions it
  hands to the covariance).  Floats are written with ``repr`` (shortest round-trip form), so
  equal text means equal bits.
- ``out/``: the bundled command outputs (``identify`` on every bundled campaign, ``study
  velocity``, ``discover grc1-oravec2009``, a ``posterior`` and a ``wheel`` run), each
  command run from DIR with a relative ``--out`` so the command line in the provenance is
  the same in every capture; what each prints to stdout and stderr goes to ``console/``.

``compare`` lists every file of either capture as identical or different (console text also
as identical but for the wall-clock times it prints); for a PDF that differs it also compares
the extracted text page by page (pypdf) and the document metadata, to tell a rendering
difference from a changed number.  Exit status 1 when any file but a PDF differs or is
missing.
"""

from __future__ import annotations

import argparse
import filecmp
import importlib
import json
import math
import re
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BUNDLED = ("simulated-paper", "cullinan-sand", "grc1-oravec2009", "cmu-3d-terramechanics")
COMMANDS = [
    *(f"identify {c} --out out/identify-{c} --progress off".split() for c in BUNDLED),
    "study velocity --out out/study-velocity".split(),
    "discover grc1-oravec2009 --out out/discover-grc1-oravec2009".split(),
    # The posterior and wheel reports draw the figures of report/posterior_figures.py and
    # report/wheel_figures.py.
    [
        *("posterior", "cullinan-sand", "--model", "bernstein", "--draws", "400"),
        *("--progress", "off", "--out", "out/posterior-cullinan-sand"),
    ],
    [
        *("wheel", "cmu-3d-terramechanics", "--progress", "off"),
        *("--out", "out/wheel-cmu-3d-terramechanics"),
    ],
]


def _plain(value):
    """JSON-ready copy of ``value``: arrays as nested lists of floats, tuples as lists."""
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)  # nan, inf: as text, so json.dumps needs no extension
    return value


def _record_fit(result, outcomes: list) -> dict:
    out = {
        name: _plain(getattr(result, name))
        for name in (
            "model_name",
            "param_names",
            "values",
            "stderr_values",
            "covariance",
            "epsilon",
            "rss",
            "nobs",
            "dof",
            "nfev",
            "niter",
            "converged",
            "message",
            "units",
            "bounds",
            "jacobian_method",
            "condition_number",
            "residuals",
        )
    }
    out["flags"] = [str(flag) for flag in result.flags]
    out["lm"] = outcomes[-1] if outcomes else None
    return out


def _line(x, a):
    return a * x


def _line_jac(x, a):
    return np.asarray(x, float)[:, None]


def _nan_jac(x, a):
    return np.full((np.size(x), 1), np.nan)


def _only_at_one(x, a):
    """a·x at a = 1 exactly, NaN elsewhere: every trial step is rejected."""
    return x * a if a == 1.0 else np.full(np.size(x), np.nan)


def _fit_cases():
    """(label, thunk) pairs: each thunk calls ``identify`` once."""
    sys.path.insert(0, str(ROOT / "tests"))
    from reference.nist import NONLINEAR_MODELS, NONLINEAR_NAMES, load_nonlinear

    from soilstats import BEKKER, BERNSTEIN, JANOSI, MOHR_COULOMB, REECE, identify
    from soilstats.models.shear import SHEAR_CURVE

    cases = []
    for name in NONLINEAR_NAMES:
        data = load_nonlinear(name)
        for start in ("start1", "start2"):
            cases.append(
                (
                    f"nist/{name}/{start}",
                    lambda d=data, n=name, s=start: identify(
                        NONLINEAR_MODELS[n], d.x, d.y, getattr(d, s)
                    ),
                )
            )
    rng = np.random.default_rng(20240601)
    b = np.repeat([0.025, 0.05, 0.075], 200)
    z = np.tile(np.linspace(5e-4, 0.05, 200), 3)
    p = BEKKER.func((b, z), -9.8e3, 1.2e6, 0.8) * (1 + rng.normal(0, 0.03, z.size))
    w = 1.0 / np.repeat([p[:200].max(), p[200:400].max(), p[400:].max()], 200)
    w_zero = w.copy()
    w_zero[::7] = 0.0
    p_bern = BERNSTEIN.func(z, 8e5, 1.1) * (1 + rng.normal(0, 0.03, z.size))
    p_reece = REECE.func((b, z), 2e4, 3e6, 0.9) * (1 + rng.normal(0, 0.03, z.size))
    sigma = np.repeat([1e4, 2e4, 4e4], 200)
    j = np.tile(np.linspace(0, 0.08, 200), 3)
    tau = JANOSI.func((sigma, j), 800.0, 31.0, 0.012) + rng.normal(0, 80, j.size)
    tau_ss = MOHR_COULOMB.func(sigma, 800.0, 31.0) + rng.normal(0, 80, sigma.size)
    tau_one = SHEAR_CURVE.func(j[:200], 1.3e4, 0.01) + rng.normal(0, 80, 200)
    warn = {"on_failure": "warn"}
    calls = {
        "model/bekker": (BEKKER, (b, z), p, [1e3, 1e6, 1.0]),
        "model/bekker-weighted": (BEKKER, (b, z), p, [1e3, 1e6, 1.0], {"weights": w}),
        "model/bekker-zero-weights": (BEKKER, (b, z), p, [0, 1e6, 1], {"weights": w_zero}),
        "model/bekker-own-jac": (BEKKER, (b, z), p, [1e3, 1e6, 1.0], {"jac": BEKKER.jac}),
        "model/bekker-bare": (BEKKER.func, (b, z), p, [1e3, 1e6, 1.0]),
        "model/bernstein": (BERNSTEIN, z, p_bern, [5e5, 1.0], {"weights": w}),
        "model/reece": (REECE, (b, z), p_reece, [1e4, 1e6, 1.0], {"weights": w}),
        "model/janosi": (JANOSI, (sigma, j), tau, [500.0, 25.0, 0.02]),
        "model/mohr-coulomb": (MOHR_COULOMB, sigma, tau_ss, [100.0, 20.0]),
        "model/shear-curve": (SHEAR_CURVE, j[:200], tau_one, [1e4, 0.02]),
        "model/bekker-one-iteration": (BEKKER, (b, z), p, [1, 1e6, 1], {"max_iter": 1, **warn}),
        "model/janosi-2-iterations": (JANOSI, (sigma, j), tau, [1, 1, 1], {"max_iter": 2, **warn}),
        # every stopping rule of the optimiser
        "stop/zero-residual": (_line, z, 3.0 * z, [3.0], {"jac": _line_jac}),
        "stop/xtol-exact-data": (_line, z, 3.0 * z, [1.0], {"jac": _line_jac}),
        "stop/gtol": (JANOSI, (sigma, j), tau, [500, 25, 0.02], {"gtol": 1e-3}),
        "stop/large-ftol": (JANOSI, (sigma, j), tau, [500, 25, 0.02], {"ftol": 1e-4}),
        "stop/jacobian-not-finite": (_line, z, p, [1.0], {"jac": _nan_jac, **warn}),
        "stop/damping-exhausted": (
            _only_at_one,
            z,
            1e135 * p,
            [1.0],
            {"jac": _line_jac, "xtol": 0, "ftol": 0, **warn},
        ),
        # invalid input: the messages are part of the behaviour
        "error/on-failure": (BEKKER, (b, z), p, [1, 1, 1], {"on_failure": "x"}),
        "error/names": (np.multiply, z, p, [1.0], {"param_names": ("a", "b")}),
        "error/too-few": (BERNSTEIN, z[:2], p[:2], [1.0, 1.0]),
        "error/nan-y": (BERNSTEIN, z, np.where(z > 0.04, np.nan, p), [1, 1]),
        "error/inf-weight": (BERNSTEIN, z, p, [1, 1], {"weights": np.full(z.size, np.inf)}),
        "error/negative-weight": (BERNSTEIN, z, p, [1, 1], {"weights": -w}),
        "error/zero-weights": (BERNSTEIN, z, p, [1, 1], {"weights": np.eye(1, z.size)[0]}),
        "error/not-finite-start": (BERNSTEIN.func, z, p, [np.nan, 1.0], warn),
    }
    for label, call in calls.items():
        args, kwargs = (call[:-1], call[-1]) if isinstance(call[-1], dict) else (call, {})
        cases.append((label, lambda a=args, k=kwargs: identify(*a, **k)))
    return cases


def capture_fits(path: Path) -> None:
    """Write ``fits.json``: every case's FitResult and raw LMOutcome (or its error text)."""
    from soilstats import ConvergenceError

    # The module, not the function of the same name that soilstats.fitting exports.
    identify_module = importlib.import_module("soilstats.fitting.identify")

    outcomes: list = []
    original = identify_module.levenberg_marquardt

    def recording(*args, **kwargs):
        out = original(*args, **kwargs)
        outcomes.append(
            {
                "params": _plain(out.params),
                "cost": _plain(out.cost),
                "nfev": out.nfev,
                "njev": out.njev,
                "niter": out.niter,
                "converged": out.converged,
                "reason": out.reason,
                "jacobian": _plain(out.jacobian),
                "gram": _plain(out.gram),
                "scaled": _plain(out.scaled),
            }
        )
        return out

    identify_module.levenberg_marquardt = recording
    records = {}
    try:
        for label, thunk in _fit_cases():
            outcomes.clear()
            try:
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    result = thunk()
                records[label] = _record_fit(result, outcomes)
                records[label]["warnings"] = [str(w.message) for w in caught]
            except ConvergenceError as err:
                records[label] = _record_fit(err.result, outcomes)
                records[label]["raised"] = f"{type(err).__name__}: {err}"
            except Exception as err:  # the invalid-input cases
                records[label] = {"raised": f"{type(err).__name__}: {err}"}
    finally:
        identify_module.levenberg_marquardt = original
    path.write_text(json.dumps(records, indent=1, sort_keys=True) + "\n")


def capture(directory: Path, only: set[str] | None = None) -> None:
    """Write the fits and the command outputs (only the commands named in ``only``)."""
    directory.mkdir(parents=True)
    capture_fits(directory / "fits.json")
    for argv in COMMANDS:
        if only is not None and argv[0] not in only:
            continue
        print("soilstats", " ".join(argv), flush=True)
        run = subprocess.run(
            [sys.executable, "-m", "soilstats", *argv],
            cwd=directory,
            check=True,
            capture_output=True,
        )
        # What the command prints is behaviour too (messages, tables).
        stem = directory / "console" / Path(argv[argv.index("--out") + 1]).name
        stem.parent.mkdir(exist_ok=True)
        stem.with_suffix(".stdout").write_bytes(run.stdout)
        stem.with_suffix(".stderr").write_bytes(run.stderr)


def _pdf_differences(a: Path, b: Path) -> str:
    """What differs between two PDFs: page count, text per page, metadata."""
    try:
        from pypdf import PdfReader
    except ImportError:  # pragma: no cover - pypdf is a test extra
        return "pypdf not installed: bytes differ, text not compared"
    ra, rb = PdfReader(a), PdfReader(b)
    if len(ra.pages) != len(rb.pages):
        return f"page count {len(ra.pages)} vs {len(rb.pages)}"
    pages = [
        i + 1
        for i, (pa, pb) in enumerate(zip(ra.pages, rb.pages, strict=True))
        if pa.extract_text() != pb.extract_text()
    ]
    meta = {
        key
        for key in set(ra.metadata or {}) | set(rb.metadata or {})
        if (ra.metadata or {}).get(key) != (rb.metadata or {}).get(key)
    }
    parts = [f"text differs on pages {pages}" if pages else "text identical on every page"]
    parts.append(f"metadata differs in {sorted(meta)}" if meta else "metadata identical")
    return "; ".join(parts)


def _first_difference(a: Path, b: Path) -> str:
    """The first line that differs between two text files, both versions, cut short."""
    lines_a = a.read_text(errors="replace").splitlines()
    lines_b = b.read_text(errors="replace").splitlines()
    for number, (x, y) in enumerate(zip(lines_a, lines_b, strict=False), start=1):
        if x != y:
            return f" (line {number}: {x.strip()[:80]!r} vs {y.strip()[:80]!r})"
    return f" ({len(lines_a)} vs {len(lines_b)} lines)"


def _untimed(path: Path) -> str:
    """A console text with its wall-clock times ("runtime 0.2 s", "3.1 s") masked."""
    return re.sub(r"\b\d+(\.\d+)? s\b", "<t> s", path.read_text())


def compare(base: Path, new: Path) -> int:
    files = sorted(
        {p.relative_to(base) for p in base.rglob("*") if p.is_file()}
        | {p.relative_to(new) for p in new.rglob("*") if p.is_file()}
    )
    failures = 0
    for rel in files:
        a, b = base / rel, new / rel
        if not (a.exists() and b.exists()):
            status = f"only in {'base' if a.exists() else 'new'}"
            failures += rel.suffix != ".pdf"
        elif filecmp.cmp(a, b, shallow=False):
            status = "identical"
        elif rel.suffix == ".pdf":
            status = "DIFFERS (" + _pdf_differences(a, b) + ")"
        elif rel.parts[0] == "console" and _untimed(a) == _untimed(b):
            status = "identical but for wall-clock times"
        else:
            status = "DIFFERS" + _first_difference(a, b)
            failures += 1
        print(f"{status:>10}  {rel}")
    print(f"{len(files)} files, {failures} JSON/CSV/text file(s) differ or are missing")
    return 1 if failures else 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="action", required=True)
    take = sub.add_parser("capture")
    take.add_argument("directory", type=Path)
    take.add_argument(
        "--only",
        type=lambda text: set(text.split(",")),
        help="comma-separated commands to run (default: all of them)",
    )
    both = sub.add_parser("compare")
    both.add_argument("base", type=Path)
    both.add_argument("new", type=Path)
    argv = sys.argv[1:] if argv is None else argv
    if argv == ["--smoke"]:  # tests/test_benchmarks.py: the fits and `identify`, compared
        with tempfile.TemporaryDirectory() as tmp:
            capture(Path(tmp) / "a", {"identify"})
            return compare(Path(tmp) / "a", Path(tmp) / "a")
    args = parser.parse_args(argv)
    if args.action == "capture":
        capture(args.directory, args.only)
        return 0
    return compare(args.base, args.new)


if __name__ == "__main__":
    sys.exit(main())
