"""One vocabulary for the evidence of a held-out gain, used by every command and report.

A held-out gain is the mean paired difference d̄ of out-of-sample errors (base model minus
extended model, per held-out test, run or condition) with its standard error SE. Every
report prints it as ``d̄ ± SE (z SE)`` and names it with one of three words:

* **real**: d̄ ≥ :data:`REAL_SE` standard errors (2) and the extended model's error lower —
  the only case in which soilstats calls a gain real;
* **weak**: a positive gain below that — it may be noise; said as "weak (1.4 SE; real needs 2)";
* **none**: no gain (d̄ ≤ 0, or the extended model's error is not lower).

Why 2 SE: a paired mean more than two standard errors above zero arises by chance about one
time in forty (one-sided, normal); it is the conventional line and the one a reader assumes.
A rule that keeps an extension on less (discover keeps one at 1 SE, because the cause has
already passed a Holm-controlled test; docs/discover.md "Gain") says "kept" and the word
for its evidence, never "real".

Use (docs/conventions.md, "Evidence of a gain")::

    from soilstats import evidence
    evidence.verdict(d, se)                  # "real" | "weak" | "none"
    evidence.is_real(d, se)                  # bool, the same rule
    evidence.gain_text(d, se, unit="mm", scale=1e3)   # "2.10 ± 0.52 mm (4.0 SE)"
    evidence.describe(d, se)                 # "real: 0.021 ± 0.0052 (4.0 SE)"
"""

from __future__ import annotations

import math

__all__ = [
    "NONE",
    "REAL",
    "REAL_SE",
    "RULE",
    "WEAK",
    "describe",
    "gain_text",
    "is_real",
    "verdict",
    "z_score",
]

#: A gain is real when its mean paired difference is at least this many standard errors.
REAL_SE = 2.0

REAL, WEAK, NONE = "real", "weak", "none"

#: The rule in one sentence, for reports' methods sections and notes.
RULE = (
    f"a held-out gain is called real only when the mean paired difference of the "
    f"out-of-sample errors is at least {REAL_SE:g} standard errors above zero; a smaller "
    "positive gain is weak, a zero or negative one none"
)


def z_score(difference: float, stderr: float) -> float:
    """d̄/SE; +inf for a positive difference with SE 0, NaN for no information."""
    difference, stderr = float(difference), float(stderr)
    if not math.isfinite(difference):
        return float("nan")
    if not math.isfinite(stderr) or stderr <= 0:
        if stderr == 0 and difference > 0:
            return float("inf")
        return float("nan")
    return difference / stderr


def verdict(difference: float, stderr: float, relative: float | None = None) -> str:
    """The word for a held-out gain: ``"real"``, ``"weak"`` or ``"none"`` (module docstring).

    ``difference``: mean paired difference base − extended (positive: the extension predicts
    better); ``stderr``: its standard error; ``relative``: 1 − extended/base where known (a
    gain whose relative error is not lower is none, whatever the paired mean says).
    """
    difference = float(difference)
    if not difference > 0 or (relative is not None and not float(relative) > 0):
        return NONE
    z = z_score(difference, stderr)
    return REAL if z >= REAL_SE else WEAK


def is_real(difference: float, stderr: float, relative: float | None = None) -> bool:
    """Whether :func:`verdict` says ``"real"``."""
    return verdict(difference, stderr, relative) == REAL


def gain_text(
    difference: float, stderr: float, *, unit: str = "", scale: float = 1.0, digits: int = 3
) -> str:
    """``"0.0210 ± 0.0052 (4.0 SE)"``: the gain, its standard error and z, with ``unit`` after
    the numbers (each multiplied by ``scale``, e.g. 1e3 for m -> mm)."""
    d, se = float(difference) * scale, float(stderr) * scale
    z = z_score(difference, stderr)
    unit = f" {unit}" if unit else ""
    z_text = "z n/a" if math.isnan(z) else ("∞ SE" if math.isinf(z) else f"{_z_digits(z)} SE")
    return f"{d:.{digits}g} ± {se:.2g}{unit} ({z_text})"


def _z_digits(z: float) -> str:
    """z to one decimal, or to two (cut, not rounded) where one would round a weak gain up to
    the threshold: 1.96 SE, never "2.0 SE; real needs 2"."""
    if z < REAL_SE <= round(z, 1):
        return f"{math.floor(z * 100) / 100:.2f}"
    return f"{z:.1f}"


def describe(
    difference: float,
    stderr: float,
    relative: float | None = None,
    *,
    unit: str = "",
    scale: float = 1.0,
) -> str:
    """``"real: 0.021 ± 0.0052 (4.0 SE)"``, ``"weak: … (1.4 SE; real needs 2)"``, ``"none: …"``."""
    word = verdict(difference, stderr, relative)
    text = gain_text(difference, stderr, unit=unit, scale=scale)
    if word == WEAK:
        text = text[:-1] + f"; real needs {REAL_SE:g})"
    return f"{word}: {text}"
