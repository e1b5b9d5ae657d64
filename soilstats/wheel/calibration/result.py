"""The result of a wheel calibration: its posterior, its prior layout, and what it predicts.

:class:`WheelCalibration` holds the posterior draws on the sampling scale (:class:`Layout`:
the whitened plate parameters of :class:`PlatePrior`, then the wheel inputs of
:mod:`.inputs`), the runs it was calibrated on and the discrepancy of each quantity; it
predicts any run — measured or not — as model(x, θ) + δ(x) + ε over its posterior draws
(:meth:`~WheelCalibration.samples`, :meth:`~WheelCalibration.predict`), and saves to / loads
from ArviZ netCDF (:meth:`~WheelCalibration.to_netcdf`, :func:`load_calibration`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import InputError
from ...outputs import write_atomic
from ...outputs.files import netcdf_bytes
from ..geometry import Wheel
from .discrepancy import Discrepancy
from .inputs import InputPrior
from .physics import RunDesign, simulate

__all__ = [
    "Layout",
    "PlatePrior",
    "WheelCalibration",
    "band_frame",
    "design_inputs",
    "load_calibration",
    "quantiles",
    "wheel_codes",
]

UNITS = {"sinkage_m": "m", "drawbar_pull_N": "N", "lateral_force_N": "N"}


@dataclass(frozen=True)
class PlatePrior:
    """The plate posterior as a multivariate normal: x = mean + chol·z, z ~ N(0, I).

    ``log`` marks the parameters modelled on a log scale (all their draws positive).
    """

    names: tuple[str, ...]
    log: tuple[bool, ...]
    mean: np.ndarray
    chol: np.ndarray
    source: str

    @classmethod
    def from_draws(cls, draws: pd.DataFrame, names: Sequence[str], source: str) -> PlatePrior:
        values = draws[list(names)].to_numpy(float)
        log = tuple(bool(np.all(values[:, i] > 0)) for i in range(len(names)))
        t = np.where(log, np.log(np.where(values > 0, values, 1.0)), values)
        cov = np.atleast_2d(np.cov(t, rowvar=False))
        cov += 1e-12 * np.diag(np.diag(cov))
        return cls(tuple(names), log, t.mean(axis=0), np.linalg.cholesky(cov), source)

    def values(self, z: np.ndarray) -> dict[str, np.ndarray]:
        """Law parameters (P,) from whitened z (P, d)."""
        t = self.mean + z @ self.chol.T
        return {
            n: (np.exp(t[:, i]) if lg else t[:, i])
            for i, (n, lg) in enumerate(zip(self.names, self.log, strict=True))
        }

    def to_dict(self) -> dict:
        return {
            "names": list(self.names),
            "log": list(self.log),
            "mean": self.mean.tolist(),
            "chol": self.chol.tolist(),
            "source": self.source,
        }

    @classmethod
    def from_dict(cls, d: Mapping) -> PlatePrior:
        return cls(
            tuple(d["names"]),
            tuple(d["log"]),
            np.asarray(d["mean"]),
            np.asarray(d["chol"]),
            d["source"],
        )


@dataclass(frozen=True)
class Layout:
    """Names of the sampled vector: whitened plate z's, then the wheel inputs."""

    plate: PlatePrior
    inputs: tuple[InputPrior, ...]
    fixed: tuple[tuple[str, float], ...] = ()

    @property
    def names(self) -> list[str]:
        return [f"z_{n}" for n in self.plate.names] + [p.name for p in self.inputs]

    @property
    def dim(self) -> int:
        return len(self.plate.names) + len(self.inputs)

    @property
    def with_shear(self) -> bool:
        return any(p.name == "c_kPa" for p in self.inputs)

    def params(self, theta: np.ndarray) -> dict[str, np.ndarray]:
        theta = np.atleast_2d(theta)
        d = len(self.plate.names)
        out = self.plate.values(theta[:, :d])
        out.update({p.name: theta[:, d + i] for i, p in enumerate(self.inputs)})
        out.update({name: np.full(len(theta), value) for name, value in self.fixed})
        return out

    def log_prior(self, theta: np.ndarray) -> np.ndarray:
        theta = np.atleast_2d(theta)
        d = len(self.plate.names)
        lp = -0.5 * np.sum(theta[:, :d] ** 2, axis=1)
        for i, p in enumerate(self.inputs):
            lp = lp + p.log_pdf(theta[:, d + i])
        return lp

    def prior_residuals(self, theta: np.ndarray) -> np.ndarray:
        d = len(self.plate.names)
        out = list(theta[:d])
        out += [(theta[d + i] - p.mean) / p.sd for i, p in enumerate(self.inputs) if p.sd]
        return np.asarray(out)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        d = len(self.plate.names)
        lo = np.r_[np.full(d, -np.inf), [p.low for p in self.inputs]]
        hi = np.r_[np.full(d, np.inf), [p.high for p in self.inputs]]
        return lo, hi

    def start(self) -> np.ndarray:
        return np.r_[np.zeros(len(self.plate.names)), [p.start() for p in self.inputs]]


@dataclass(frozen=True, eq=False)
class WheelCalibration:
    """Posterior of a wheel calibration and what it needs to predict new runs.

    ``chain`` (walkers, draws, dim) on the sampling scale (names ``names``); ``design`` the
    runs it was calibrated on; ``discrepancy`` one :class:`Discrepancy` per quantity;
    ``flags`` convergence problems (empty: converged); ``law`` the plate law.
    """

    law: str
    layout: Layout
    chain: np.ndarray = field(repr=False)
    design: RunDesign = field(repr=False)
    wheels: dict[str, Wheel]
    discrepancy: dict[str, Discrepancy]
    flags: tuple[str, ...]
    runtime_s: float
    rhat_max: float
    ess_min: float

    @property
    def names(self) -> list[str]:
        return self.layout.names

    @property
    def converged(self) -> bool:
        return not self.flags

    @property
    def quantities(self) -> tuple[str, ...]:
        return tuple(self.discrepancy)

    def flat(self) -> np.ndarray:
        return self.chain.reshape(-1, self.layout.dim)

    def parameter_table(self) -> pd.DataFrame:
        """Posterior mean, sd and 5/95 % quantiles of every physical input (natural units)."""
        p = self.layout.params(self.flat())
        rows = []
        for name, v in p.items():
            nat, unit = _natural(name, v)
            rows.append(
                {
                    "name": nat[0],
                    "unit": unit,
                    "mean": float(np.mean(nat[1])),
                    "sd": float(np.std(nat[1])),
                    "q05": float(np.quantile(nat[1], 0.05)),
                    "q95": float(np.quantile(nat[1], 0.95)),
                }
            )
        return pd.DataFrame(rows).set_index("name")

    def samples(
        self,
        runs: RunDesign,
        *,
        wheels: Mapping[str, Wheel] | None = None,
        n_draws: int = 400,
        seed: int = 0,
        discrepancy: bool = True,
        wheel_amplitude: Mapping[str, float] | None = None,
        datum: bool = True,
    ) -> dict[str, np.ndarray]:
        """Predictive draws (n_draws, R) of every quantity at ``runs`` (their slip, β, load,
        wheel), plus ``torque_Nm`` where the shear is carried.

        Each posterior draw gives model(x, θ) + the discrepancy's conditional mean given that
        draw's residuals on the calibration runs + a normal draw of its conditional variance
        and the repeat scatter σ.  ``discrepancy=False``: the calibrated model alone
        (parameter uncertainty and σ).  A quantity the calibration did not see measured
        (torque here) carries parameter uncertainty only (:attr:`uncalibrated`).

        ``datum=False`` leaves out the sinkage datum offset (a property of how the calibration
        runs were measured, not of a wheel): the prediction of a wheel's true sinkage.

        A wheel type the calibration did not see takes the wheel part of the discrepancy at
        its full variance τ_w²; where the calibration saw one wheel type only τ_w is unknown
        and must be stated per quantity in ``wheel_amplitude`` (an error otherwise).
        """
        wheels = {**self.wheels, **dict(wheels or {})}
        missing = sorted(set(runs.wheel) - set(wheels))
        if missing:
            raise InputError(f"no geometry for wheel type(s) {missing}: pass wheels=")
        rng = np.random.default_rng(seed)
        flat = self.flat()
        pick = rng.choice(len(flat), size=min(n_draws, len(flat)), replace=False)
        params = self.layout.params(flat[np.sort(pick)])
        shear = self.layout.with_shear
        with np.errstate(all="ignore"):
            new_params = params if datum else {**params, "datum_mm": 0.0 * params["datum_mm"]}
            new = simulate(new_params, runs, wheels, self.law, n_nodes=16, with_shear=shear)
            old = simulate(params, self.design, self.wheels, self.law, n_nodes=16, with_shear=shear)
        codes = wheel_codes(self.design)
        x_old, x_new = design_inputs(self.design, codes), design_inputs(runs, codes)
        out: dict[str, np.ndarray] = {}
        unseen = sorted(set(runs.wheel) - set(self.design.wheel))
        for q, disc in self.discrepancy.items():
            have = np.isfinite(self.design.measured[q])
            model_new = new[q]
            if unseen and not np.isfinite(disc.wheel_amplitude):
                if q not in (wheel_amplitude or {}):
                    raise InputError(
                        f"wheel type(s) {unseen} were not in the calibration, which saw one "
                        f"wheel type only: how much a new wheel's discrepancy of {q} differs "
                        "is unknown; state it (wheel_amplitude=) or calibrate on two wheel types"
                    )
                disc = replace(disc, wheel_amplitude=float(wheel_amplitude[q]))  # type: ignore[index]
            if discrepancy:
                resid = self.design.measured[q][have][None, :] - old[q][:, have]
                ok = np.all(np.isfinite(resid), axis=1)
                mean, var = disc.conditional(x_old[have], np.where(ok[:, None], resid, 0.0), x_new)
                mean[~ok] = np.nan
                sd = np.sqrt(var + disc.noise**2)
            else:
                mean, sd = np.zeros_like(model_new), np.full(len(runs), disc.noise)
            out[q] = model_new + mean + sd[None, :] * rng.standard_normal(model_new.shape)
        for q in self.uncalibrated:
            out[q] = new[q]
        if shear and np.any(runs.beta_deg != 0) and "lateral_force_N" not in out:
            out["lateral_force_N"] = new["lateral_force_N"]
        return out

    @property
    def uncalibrated(self) -> tuple[str, ...]:
        """Predicted quantities no measurement calibrated (parameter uncertainty only)."""
        shear = ("drawbar_pull_N", "torque_Nm") if self.layout.with_shear else ()
        return tuple(q for q in shear if q not in self.discrepancy)

    def predict(
        self,
        runs: RunDesign,
        *,
        wheels: Mapping[str, Wheel] | None = None,
        n_draws: int = 400,
        prob: float = 0.9,
        seed: int = 0,
        discrepancy: bool = True,
        wheel_amplitude: Mapping[str, float] | None = None,
    ) -> pd.DataFrame:
        """Bands of :meth:`samples` per run: ``{q}_median``, ``{q}_lower``, ``{q}_upper`` and
        ``{q}_not_carried`` (share of draws whose soil cannot carry the load)."""
        draws = self.samples(
            runs,
            wheels=wheels,
            n_draws=n_draws,
            seed=seed,
            discrepancy=discrepancy,
            wheel_amplitude=wheel_amplitude,
        )
        return band_frame(runs.run_id, draws, prob)

    def summary(self) -> str:
        lines = [
            f"Wheel calibration ({self.law} plate law, {len(self.design)} runs, "
            f"{self.chain.shape[0]} walkers × {self.chain.shape[1]} draws, "
            f"{self.runtime_s:.1f} s)",
            f"converged: {'yes' if self.converged else 'NO — ' + '; '.join(self.flags)} "
            f"(R-hat max {self.rhat_max:.3f}, ESS min {self.ess_min:.0f})",
            "",
            f"{'input':<10} {'unit':<10} {'mean':>11} {'sd':>10} {'5 %':>11} {'95 %':>11}",
        ]
        for name, r in self.parameter_table().iterrows():
            lines.append(
                f"{name:<10} {r['unit']:<10} {r['mean']:>11.4g} {r['sd']:>10.3g} "
                f"{r['q05']:>11.4g} {r['q95']:>11.4g}"
            )
        lines.append("")
        for q, d in self.discrepancy.items():
            lines.append(
                f"discrepancy of {q}: amplitude {d.amplitude:.3g} {UNITS[q]}, slip length "
                f"{d.length_slip:.2f}, β length {d.length_beta_deg:.0f}°, repeat scatter "
                f"{d.noise:.3g} {UNITS[q]}"
            )
        return "\n".join(lines)

    def to_netcdf(self, path: str | os.PathLike[str]) -> None:
        """Save as ArviZ netCDF: the posterior group holds the sampled vector; the attributes
        hold the law, plate prior, input priors, wheels, discrepancy and calibration runs."""
        from ...bayes._arviz import az  # deferred: arviz, 2 s (only to write)

        post = {n: self.chain[:, :, i] for i, n in enumerate(self.names)}
        idata = az.from_dict(posterior=post)
        meta = {
            "law": self.law,
            "plate_prior": self.layout.plate.to_dict(),
            "inputs": [p.to_dict() for p in self.layout.inputs],
            "fixed": dict(self.layout.fixed),
            "wheels": {k: w.to_dict() for k, w in self.wheels.items()},
            "discrepancy": {k: d.to_dict() for k, d in self.discrepancy.items()},
            "design": _design_dict(self.design),
            "flags": list(self.flags),
            "runtime_s": self.runtime_s,
            "rhat_max": self.rhat_max,
            "ess_min": self.ess_min,
        }
        idata.posterior.attrs["soilstats_wheel_calibration"] = json.dumps(meta)
        idata.posterior.attrs.pop("created_at", None)
        # built in memory, written atomically (and into a command's staged output set)
        write_atomic(Path(path), netcdf_bytes(idata))


def band_frame(run_id: np.ndarray, draws: Mapping[str, np.ndarray], prob: float) -> pd.DataFrame:
    """Equal-tailed ``prob`` bands of predictive draws (D, R) per quantity, one row per run."""
    out = pd.DataFrame({"run_id": run_id})
    tail = (1.0 - prob) / 2.0
    for q, y in draws.items():
        finite = np.isfinite(y)
        lo, med, hi = quantiles(y, (tail, 0.5, 1.0 - tail))
        out[f"{q}_median"], out[f"{q}_lower"], out[f"{q}_upper"] = med, lo, hi
        out[f"{q}_not_carried"] = 1.0 - finite.mean(axis=0)
    return out


def quantiles(y: np.ndarray, probs: Sequence[float]) -> list[np.ndarray]:
    """Quantiles over axis 0 of the finite values; NaN in a column with none."""
    y = np.asarray(y, float)
    have = np.isfinite(y).any(axis=0)
    out = [np.full(y.shape[1], np.nan) for _ in probs]
    if have.any():
        qs = np.nanquantile(y[:, have], list(probs), axis=0)
        for o, v in zip(out, qs, strict=True):
            o[have] = v
    return out


def _natural(name: str, v: np.ndarray) -> tuple[tuple[str, np.ndarray], str]:
    if name == "c_kPa":
        return ("c", v * 1e3), "Pa"
    if name == "log_K":
        return ("K", np.exp(v)), "m"
    if name == "datum_mm":
        return ("datum", v * 1e-3), "m"
    unit = {"phi": "deg"}.get(name, "-")
    return (name, v), unit


def wheel_codes(design: RunDesign) -> dict[str, int]:
    """The wheel types of a calibration's runs, numbered by sorted name (the discrepancy's
    third input: runs of one type share its wheel part)."""
    return {w: i for i, w in enumerate(sorted(set(design.wheel)))}


def design_inputs(design: RunDesign, wheel_codes: Mapping[str, int] | None = None) -> np.ndarray:
    """Discrepancy inputs (slip, β deg, wheel code); codes by sorted wheel name, new ones
    numbered after the known ones."""
    names = sorted(set(design.wheel))
    codes = dict(wheel_codes or {})
    for n in names:
        codes.setdefault(n, len(codes) + 1000)
    # β enters as its condition (the commanded level), not the measured steering angle
    return np.column_stack([design.slip, design.beta_level, [codes[str(w)] for w in design.wheel]])


def _design_dict(d: RunDesign) -> dict:
    return {
        "run_id": d.run_id.tolist(),
        "wheel": d.wheel.tolist(),
        "slip": d.slip.tolist(),
        "beta_deg": d.beta_deg.tolist(),
        "load_N": d.load_N.tolist(),
        "slip_level": d.slip_level.tolist(),
        "beta_level": d.beta_level.tolist(),
        "measured": {
            q: [None if not np.isfinite(x) else float(x) for x in v] for q, v in d.measured.items()
        },
    }


def _design_from(d: Mapping) -> RunDesign:
    arr = {k: np.asarray(d[k]) for k in ("run_id", "wheel")}
    num = {
        k: np.asarray(d[k], float)
        for k in ("slip", "beta_deg", "load_N", "slip_level", "beta_level")
    }
    meas = {
        q: np.asarray([np.nan if x is None else x for x in v], float)
        for q, v in d["measured"].items()
    }
    return RunDesign(**arr, **num, measured=meas)


def load_calibration(path: str | os.PathLike[str]) -> WheelCalibration:
    """A :class:`WheelCalibration` saved by :meth:`WheelCalibration.to_netcdf`."""
    from ...bayes._arviz import az  # deferred: arviz, 2 s (only to read)

    try:
        idata = az.from_netcdf(str(path))
        meta = json.loads(idata.posterior.attrs["soilstats_wheel_calibration"])
    except (OSError, KeyError, ValueError) as err:
        raise InputError(f"{path}: not a soilstats wheel calibration ({err})") from None
    inputs = tuple(
        InputPrior(**{k: v for k, v in p.items() if k != "kind"}) for p in meta["inputs"]
    )
    layout = Layout(
        PlatePrior.from_dict(meta["plate_prior"]), inputs, tuple(meta.get("fixed", {}).items())
    )
    chain = np.stack([idata.posterior[n].values for n in layout.names], axis=-1)
    wheels = {k: Wheel(**w) for k, w in meta["wheels"].items()}
    disc = {k: Discrepancy(**d) for k, d in meta["discrepancy"].items()}
    return WheelCalibration(
        law=meta["law"],
        layout=layout,
        chain=chain,
        design=_design_from(meta["design"]),
        wheels=wheels,
        discrepancy=disc,
        flags=tuple(meta["flags"]),
        runtime_s=float(meta["runtime_s"]),
        rhat_max=float(meta["rhat_max"]),
        ess_min=float(meta["ess_min"]),
    )
