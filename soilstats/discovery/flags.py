"""Physical red flags: identified parameters no soil can have, in their own list.

Not findings (they name no cause), but signs that the model is being forced: a negative kφ
(kc may take either sign: frictional sands give a negative kc, the paper's Table 5, as their
bearing capacity grows with width), n outside its plausible range,
kc and kφ nearly collinear (|corr| > 0.95: the plate sizes barely separate them), a friction
angle or cohesion outside (0, 90°) / ≥ 0.  Checked on each group's base fit and, for sinkage
with several velocities, per velocity (the paper's Table 5 conditions), using the health
flags every :class:`~soilstats.fitting.FitResult` carries.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ConvergenceError
from ..identification.centring import centred
from .library import base_model

if TYPE_CHECKING:
    from ..fitting.result import FitResult
    from .diagnose import Diagnosis

__all__ = ["physical_flags"]

_CODES = {"outside-bounds", "high-correlation"}


def _flags_of(
    fit: FitResult, kind: str, soil: str, scope: str, z: np.ndarray | None = None
) -> list[dict]:
    if kind == "sinkage":
        # Judge correlations where the data measure each scale, as identify does (a scale at
        # z = 1 m is correlated with n by the parametrisation alone: Cullinan's k and n at
        # +0.996 were flagged here and not by identify).
        fit = centred(fit, np.asarray([] if z is None else z, float))
    out = []
    for flag in fit.flags:
        if flag.code not in _CODES:
            continue
        code = flag.code
        if code == "high-correlation" and "kc" in flag.message and "kphi" in flag.message:
            code = "kc-kphi-collinear"
        elif code == "outside-bounds":
            code = f"implausible-{flag.message.split(' ', 1)[0]}"
        out.append(
            {"kind": kind, "soil": soil, "scope": scope, "code": code, "message": flag.message}
        )
    return out


def physical_flags(diagnoses: Iterable[Diagnosis]) -> list[dict]:
    """Red flags of every diagnosed group (its base fit, and per velocity for sinkage)."""
    out: list[dict] = []
    for d in diagnoses:
        g = d.group
        if d.base is None:
            continue
        z = g.x.get("z")
        out += _flags_of(d.base.result, g.kind, g.soil, "all tests", z)
        if g.kind != "sinkage" or "velocity_m_s" not in g.tests:
            continue
        v = np.round(g.tests["velocity_m_s"].to_numpy(float), 12)
        used = np.unique(g.owner)
        levels = np.unique(v[used][np.isfinite(v[used])])
        if levels.size < 2:
            continue
        for level in levels:
            rows = used[v[used] == level]
            model = base_model(g, rows)
            if not getattr(model, "bekker", False):
                continue
            try:
                fit = model.fit(g, rows)
            except ConvergenceError as exc:
                out.append(
                    {
                        "kind": g.kind,
                        "soil": g.soil,
                        "scope": f"velocity_m_s = {level:g}",
                        "code": "not-converged",
                        "message": str(exc),
                    }
                )
                continue
            out += _flags_of(fit.result, g.kind, g.soil, f"velocity_m_s = {level:g}", z)
    return out
