"""Numerical identification: Levenberg–Marquardt, linear least squares, results."""

from __future__ import annotations

from .identify import identify
from .linear import LinearFit, linear_least_squares
from .result import FitResult, HealthFlag, epsilon

__all__ = ["FitResult", "HealthFlag", "LinearFit", "epsilon", "identify", "linear_least_squares"]
