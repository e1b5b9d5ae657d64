"""Packaging beyond what pyproject.toml can say: ship the top-level ``studies/`` folder.

The study specifications live once, in ``studies/`` at the repository root (where users read
and copy them); the wheel installs them as ``soilstats/studies/*.toml`` so that
``python -m soilstats.study NAME`` works from any directory after ``pip install .``.
Everything else is configured in pyproject.toml.
"""

from setuptools import find_packages, setup

setup(
    packages=[*find_packages(include=["soilstats*"]), "soilstats.studies"],
    package_dir={"soilstats.studies": "studies"},
)
