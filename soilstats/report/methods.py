"""The methods section every report shares: the paper's equations, typeset and cited.

Equation numbers are those of Apfelbeck, Kuß, Rebele, Schäfer (2011), "A systematic approach
to reliably characterize soils based on Bevameter testing", J. Terramechanics 48(5).
"""

from __future__ import annotations

from .document import Document

__all__ = ["CITATION", "write_equations"]

CITATION = (
    "M. Apfelbeck, S. Kuß, B. Rebele, B. Schäfer, “A systematic approach to reliably "
    "characterize soils based on Bevameter testing”, Journal of Terramechanics 48(5), "
    "360–371, 2011"
)

# (Typst math, equation tag, what it is) per kind of test.
_SINKAGE = (
    ("p = F / A", "Eq. 6", "measured pressure of a plate of area A under the load F"),
    (
        "p = (k_c / b + k_phi) z^n",
        "Eq. 7",
        "Bekker: pressure–sinkage of a plate of width (radius) b, pooled over plate sizes",
    ),
    ("p = k z^n", "Eq. 8", "Bernstein: one plate size, per test and pooled"),
    (
        "min_theta 1/2 sum_i (w_i (p_i - p(z_i, theta)))^2, quad w_i = 1 / max_(i in t) p_i",
        "Eq. 9",
        "weighted least squares (Levenberg–Marquardt), each test t weighted by its peak",
    ),
)
_SHEAR = (
    (
        "tau = (3 T) / (2 pi (r_o^3 - r_i^3))",
        "Eq. 12",
        "shear stress of a ring of outer and inner radius r_o, r_i under the torque T",
    ),
    (
        "tau = (c + sigma tan phi)(1 - e^(-j/K))",
        "Eq. 13",
        "Janosi–Hanamoto shear curve at normal pressure σ",
    ),
    ("j = (r_o + r_i) / 2 dot alpha", "Eq. 14", "shear displacement at the ring rotation α"),
    ("tau_(s s) = c + sigma tan phi", "Eq. 15", "Mohr–Coulomb line of the steady states"),
)
_QUALITY = (
    (
        "epsilon = 1 - sqrt(sum_i e_i^2 / (N - 2)) / (sum_i |y_i| / N)",
        "Eq. 2",
        "fit quality: 1 is a perfect fit, residuals e_i of N points",
    ),
    (
        'sigma_theta = sqrt(op("diag") C), quad C = s^2 (J^T W J)^(-1)',
        "Eqs. 3–5",
        "standard deviations from the covariance of the weighted fit (Jacobian J, weights W, "
        "residual variance s²)",
    ),
)


def write_equations(
    doc: Document, kinds: tuple[str, ...] = ("sinkage", "shear"), *, columns: int = 1
) -> None:
    """The paper's model equations for ``kinds`` and the fit-quality equations, with a
    citation; ``columns`` > 1 sets them side by side (a compact methods section)."""
    doc.paragraph(
        "The soil models, the identification and the fit quality follow ",
        CITATION,
        ". Equation numbers are the paper's.",
    )
    rows: list = []
    if "sinkage" in kinds:
        rows += _SINKAGE
    if "shear" in kinds:
        rows += _SHEAR
    if columns > 1:
        doc.equations(
            ((what.capitalize() + ":", e, tag) for e, tag, what in (*rows, *_QUALITY)),
            columns=columns,
        )
        return
    for expression, tag, what in (*rows, *_QUALITY):
        doc.paragraph(what.capitalize() + ":")
        doc.equation(expression, tag)
