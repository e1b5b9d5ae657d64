"""Readers and model functions for the NIST StRD reference data sets.

The ``.dat`` files are vendored in ``tests/data/nist-strd/`` (public domain, unedited; its README
gives their provenance and layout).  Certified values are parsed by label from the file
itself, never typed in here, so a test compares against NIST's numbers and nothing else.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

NIST_DIR = Path(__file__).resolve().parents[1] / "data" / "nist-strd"


def lre(estimate: float, certified: float) -> float:
    """Log relative error: agreeing significant digits (capped at 15; absolute if certified 0)."""
    if certified == 0.0:
        err = abs(estimate)
        return 15.0 if err == 0 else -math.log10(err)
    err = abs(estimate - certified) / abs(certified)
    return 15.0 if err == 0 else min(15.0, -math.log10(err))


def _lines(path: Path) -> list[str]:
    return path.read_text().replace("\r", "").split("\n")


def _data_block(lines: list[str], ncols: int) -> np.ndarray:
    rows = []
    for line in lines[60:]:  # data always begin on line 61
        parts = line.split()
        if len(parts) == ncols:
            rows.append([float(v) for v in parts])
    return np.array(rows)


@dataclass(frozen=True)
class NonlinearSet:
    name: str
    x: np.ndarray
    y: np.ndarray
    start1: np.ndarray
    start2: np.ndarray
    certified: np.ndarray
    certified_sd: np.ndarray
    rss: float
    difficulty: str


def load_nonlinear(name: str) -> NonlinearSet:
    lines = _lines(NIST_DIR / "nonlinear" / f"{name}.dat")
    text = "\n".join(lines)
    p = int(re.search(r"(\d+)\s+Parameters", text).group(1))
    start1, start2, cert, sd = [], [], [], []
    for line in lines[40 : 40 + p]:
        vals = line.split("=")[1].split()
        start1.append(float(vals[0]))
        start2.append(float(vals[1]))
        cert.append(float(vals[2]))
        sd.append(float(vals[3]))
    rss = float(re.search(r"Residual Sum of Squares:\s+(\S+)", text).group(1))
    difficulty = re.search(r"(Lower|Average|Higher) Level of Difficulty", text).group(1).lower()
    ncols = 3 if name == "Nelson" else 2
    data = _data_block(lines, ncols)
    y = np.log(data[:, 0]) if name == "Nelson" else data[:, 0]
    x = data[:, 1:].T if ncols == 3 else data[:, 1]
    return NonlinearSet(
        name,
        x,
        y,
        np.array(start1),
        np.array(start2),
        np.array(cert),
        np.array(sd),
        rss,
        difficulty,
    )


# Model functions exactly as written in the files' "Model:" blocks, f(x, *b).  They use numpy
# ufuncs only, so they also accept complex arguments (the complex-step Jacobian relies on that).
_PI = 3.14159265358979323846

NONLINEAR_MODELS = {
    "Misra1a": lambda x, b1, b2: b1 * (1 - np.exp(-b2 * x)),
    "Chwirut2": lambda x, b1, b2, b3: np.exp(-b1 * x) / (b2 + b3 * x),
    "Chwirut1": lambda x, b1, b2, b3: np.exp(-b1 * x) / (b2 + b3 * x),
    "Lanczos3": lambda x, b1, b2, b3, b4, b5, b6: (
        b1 * np.exp(-b2 * x) + b3 * np.exp(-b4 * x) + b5 * np.exp(-b6 * x)
    ),
    "Gauss1": lambda x, b1, b2, b3, b4, b5, b6, b7, b8: (
        b1 * np.exp(-b2 * x)
        + b3 * np.exp(-((x - b4) ** 2) / b5**2)
        + b6 * np.exp(-((x - b7) ** 2) / b8**2)
    ),
    "DanWood": lambda x, b1, b2: b1 * x**b2,
    "Misra1b": lambda x, b1, b2: b1 * (1 - (1 + b2 * x / 2) ** (-2)),
    "Kirby2": lambda x, b1, b2, b3, b4, b5: (b1 + b2 * x + b3 * x**2) / (1 + b4 * x + b5 * x**2),
    "Hahn1": lambda x, b1, b2, b3, b4, b5, b6, b7: (
        (b1 + b2 * x + b3 * x**2 + b4 * x**3) / (1 + b5 * x + b6 * x**2 + b7 * x**3)
    ),
    # Nelson's response is log(y): the file states "log[y] = b1 - b2*x1 * exp[-b3*x2] + e".
    "Nelson": lambda x, b1, b2, b3: b1 - b2 * x[0] * np.exp(-b3 * x[1]),
    "MGH17": lambda x, b1, b2, b3, b4, b5: b1 + b2 * np.exp(-x * b4) + b3 * np.exp(-x * b5),
    "Misra1c": lambda x, b1, b2: b1 * (1 - (1 + 2 * b2 * x) ** (-0.5)),
    "Misra1d": lambda x, b1, b2: b1 * b2 * x * (1 + b2 * x) ** (-1),
    "Roszman1": lambda x, b1, b2, b3, b4: b1 - b2 * x - np.arctan(b3 / (x - b4)) / _PI,
    "ENSO": lambda x, b1, b2, b3, b4, b5, b6, b7, b8, b9: (
        b1
        + b2 * np.cos(2 * _PI * x / 12)
        + b3 * np.sin(2 * _PI * x / 12)
        + b5 * np.cos(2 * _PI * x / b4)
        + b6 * np.sin(2 * _PI * x / b4)
        + b8 * np.cos(2 * _PI * x / b7)
        + b9 * np.sin(2 * _PI * x / b7)
    ),
    "MGH09": lambda x, b1, b2, b3, b4: b1 * (x**2 + x * b2) / (x**2 + x * b3 + b4),
    "Thurber": lambda x, b1, b2, b3, b4, b5, b6, b7: (
        (b1 + b2 * x + b3 * x**2 + b4 * x**3) / (1 + b5 * x + b6 * x**2 + b7 * x**3)
    ),
    "BoxBOD": lambda x, b1, b2: b1 * (1 - np.exp(-b2 * x)),
    "Rat42": lambda x, b1, b2, b3: b1 / (1 + np.exp(b2 - b3 * x)),
    "MGH10": lambda x, b1, b2, b3: b1 * np.exp(b2 / (x + b3)),
    "Eckerle4": lambda x, b1, b2, b3: (b1 / b2) * np.exp(-0.5 * ((x - b3) / b2) ** 2),
    "Rat43": lambda x, b1, b2, b3, b4: b1 / ((1 + np.exp(b2 - b3 * x)) ** (1 / b4)),
    "Bennett5": lambda x, b1, b2, b3: b1 * (b2 + x) ** (-1 / b3),
}
NONLINEAR_MODELS["Gauss2"] = NONLINEAR_MODELS["Gauss1"]
NONLINEAR_MODELS["Gauss3"] = NONLINEAR_MODELS["Gauss1"]
NONLINEAR_MODELS["Lanczos1"] = NONLINEAR_MODELS["Lanczos3"]
NONLINEAR_MODELS["Lanczos2"] = NONLINEAR_MODELS["Lanczos3"]

NONLINEAR_NAMES = sorted(NONLINEAR_MODELS)


# -- linear regression sets -------------------------------------------------------------------
@dataclass(frozen=True)
class LinearSet:
    name: str
    design: np.ndarray  # (N, p) design matrix built from the file's model statement
    y: np.ndarray
    certified: np.ndarray
    certified_sd: np.ndarray
    residual_sd: float
    r_squared: float
    has_intercept: bool


_POLY_DEGREE = {"Norris": 1, "Pontius": 2, "Filip": 10, **{f"Wampler{i}": 5 for i in range(1, 6)}}


def load_linear(name: str) -> LinearSet:
    lines = _lines(NIST_DIR / "linear" / f"{name}.dat")
    text = "\n".join(lines)
    est, sd = [], []
    for line in lines[30:]:
        parts = line.split()
        if len(parts) == 3 and re.fullmatch(r"B\d+", parts[0]):
            est.append(float(parts[1]))
            sd.append(float(parts[2]))
        elif est and not parts:
            break
    residual_sd = float(re.search(r"Residual\s+Standard Deviation\s+(\S+)", text).group(1))
    r2 = float(re.search(r"R-Squared\s+(\S+)", text).group(1))
    ncols = 7 if name == "Longley" else 2
    data = _data_block(lines, ncols)
    y = data[:, 0]
    if name == "Longley":
        design = np.column_stack([np.ones(len(y)), data[:, 1:]])
        intercept = True
    elif name.startswith("NoInt"):
        design = data[:, 1:2]
        intercept = False
    else:
        x = data[:, 1]
        design = np.vander(x, _POLY_DEGREE[name] + 1, increasing=True)
        intercept = True
    return LinearSet(name, design, y, np.array(est), np.array(sd), residual_sd, r2, intercept)


LINEAR_NAMES = ["Norris", "Pontius", "NoInt1", "NoInt2", "Filip", "Longley"] + [
    f"Wampler{i}" for i in range(1, 6)
]


# -- one-way ANOVA sets -----------------------------------------------------------------------
@dataclass(frozen=True)
class AnovaSet:
    name: str
    treatment: np.ndarray  # integer labels, first data column
    response: np.ndarray
    response_text: tuple[str, ...]  # the response exactly as printed, for exact arithmetic
    df_between: int
    ss_between: float
    ms_between: float
    f: float
    df_within: int
    ss_within: float
    ms_within: float
    r_squared: float
    residual_sd: float


def load_anova(name: str) -> AnovaSet:
    """Data and certified values of one NIST StRD ANOVA set, the values parsed by label.

    AtmWtAg's certified block sits one line lower than its header says, hence labels, not lines.
    """
    lines = _lines(NIST_DIR / "anova" / f"{name}.dat")
    text = "\n".join(lines[:60])
    num = r"([-+0-9.Ee]+)"
    between = re.search(rf"^Between \w+\s+(\d+)\s+{num}\s+{num}\s+{num}\s*$", text, re.M)
    within = re.search(rf"^Within \w+\s+(\d+)\s+{num}\s+{num}\s*$", text, re.M)
    r2 = float(re.search(rf"Certified R-Squared\s+{num}", text).group(1))
    sd = float(re.search(rf"Standard Deviation\s+{num}", text).group(1))
    treatment, response = [], []
    for line in lines[60:]:
        parts = line.split()
        if len(parts) == 2:
            treatment.append(int(parts[0]))
            response.append(parts[1])
    return AnovaSet(
        name,
        np.array(treatment),
        np.array([float(v) for v in response]),
        tuple(response),
        int(between.group(1)),
        float(between.group(2)),
        float(between.group(3)),
        float(between.group(4)),
        int(within.group(1)),
        float(within.group(2)),
        float(within.group(3)),
        r2,
        sd,
    )


ANOVA_NAMES = ["SiRstv", *(f"SmLs{i:02d}" for i in range(1, 10)), "AtmWtAg"]
