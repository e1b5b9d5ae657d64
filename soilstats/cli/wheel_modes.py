"""The calibration and prediction modes of ``soilstats wheel``: parse, call, print.

``--calibrate`` calibrates the wheel on the runs and validates it held out
(:func:`soilstats.wheel.calibration.calibrate_and_validate`); ``--calibration FILE`` applies a
saved calibration to the runs; ``--predict`` predicts a rover team's own wheel
(:func:`soilstats.wheel.calibration.predict_own_wheel`).
"""

from __future__ import annotations

import argparse
import io
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import InputError
from ..outputs import json_safe, output_path, write_atomic, write_csv, write_json
from .common import defaults_not_given, prepared, progress_enabled

if TYPE_CHECKING:
    import pandas as pd

    from ..outputs.provenance import Provenance
    from ..wheel import Wheel
    from ..wheel.calibration.validate import CalibrationReport
    from ..wheel.soil import PlateDraws

CALIBRATION_FILE = "wheel_calibration.nc"
#: Options of one mode only (left out of another mode's "defaults").
PREDICT_OPTIONS = (
    "--load",
    "--slips",
    "--slip-angle",
    "--pull",
    "--wheel-type",
    "--discrepancy-prior",
)
CALIBRATE_OPTIONS = ("--scope", "--calibration-draws", "--fold-draws")
PREDICT_OUTPUTS = ("wheel.json", "wheel.pdf", "wheel_draws.nc", "wheel_draws.csv")


def configure(parser: argparse.ArgumentParser) -> None:
    """The options of the calibration and prediction modes."""
    group = parser.add_argument_group("calibration and prediction (docs/wheel.md)")
    group.add_argument(
        "--calibrate",
        action="store_true",
        help="calibrate the wheel on the runs (emcee, with a model-discrepancy term) and "
        f"validate it on held-out slip conditions and wheels; --out writes {CALIBRATION_FILE}",
    )
    group.add_argument(
        "--calibration",
        metavar="FILE",
        help=f"a saved calibration ({CALIBRATION_FILE}) applied to the runs, or to --predict",
    )
    group.add_argument(
        "--predict",
        action="store_true",
        help="predict your own wheel (--wheel-radius, --wheel-width, --load, --slips): bands, "
        "P(drawbar pull < 0) per slip, the slip for --pull; no runs file needed",
    )
    group.add_argument("--load", type=float, metavar="W", help="--predict: normal load [N]")
    group.add_argument(
        "--slips",
        metavar="A:B:STEP",
        default="-0.5:0.9:0.1",
        help="--predict: slips from A to B in steps (default -0.5:0.9:0.1)",
    )
    group.add_argument(
        "--slip-angle", type=float, default=0.0, metavar="DEG", help="--predict: slip angle β"
    )
    group.add_argument(
        "--pull", type=float, metavar="F", help="--predict: the drawbar pull [N] you need"
    )
    group.add_argument(
        "--wheel-type",
        default="own",
        metavar="NAME",
        help="--predict: name of your wheel type (a calibrated type's name applies its own "
        "discrepancy; default own)",
    )
    group.add_argument(
        "--discrepancy-prior",
        choices=("none", "cmu"),
        default="none",
        help="--predict without a calibration: add the discrepancy learned on the CMU runs as a "
        "stated prior (default none: the band is parameter uncertainty only)",
    )
    group.add_argument(
        "--scope",
        choices=("beta0", "all"),
        default="beta0",
        help="--calibrate: the runs at slip angle 0 (default), or all runs (the slip-angle "
        "model, validated also by leaving each slip angle out; slow)",
    )
    group.add_argument(
        "--calibration-draws",
        type=int,
        default=8000,
        help="kept draws of the calibration (default 8000)",
    )
    group.add_argument(
        "--fold-draws",
        type=int,
        default=2000,
        help="kept draws of each held-out fold's calibration (default 2000)",
    )


def check_modes(args: argparse.Namespace) -> None:
    """Refuse combinations that cannot mean anything, before any work."""
    if args.calibrate and args.calibration:
        raise InputError("--calibrate makes a calibration; --calibration applies one: not both")
    if args.predict and args.calibrate:
        raise InputError(
            "--predict takes a saved calibration (--calibration FILE), not "
            "--calibrate: calibrate first, then predict with the file"
        )
    if args.predict and (args.load is None or not args.load > 0):
        raise InputError("--predict needs --load W (the wheel's normal load in N, > 0)")
    for option in ("calibration_draws", "fold_draws"):
        if getattr(args, option) < 400:
            raise InputError(f"--{option.replace('_', '-')} must be at least 400")


def calibrate(
    args: argparse.Namespace,
    runs: pd.DataFrame,
    wheels: dict[str, Wheel],
    plate: PlateDraws,
    priors: dict,
    progress: bool,
) -> tuple[dict, CalibrationReport]:
    """``--calibrate``: (the JSON part, the report object)."""
    from ..wheel.calibration import RunDesign  # deferred: arviz
    from ..wheel.calibration.validate import calibrate_and_validate  # deferred: arviz

    scope = runs if args.scope == "all" else runs[runs["beta_level"] == 0]
    design = RunDesign.from_runs(scope.reset_index(drop=True))
    report = calibrate_and_validate(
        design,
        wheels,
        plate.draws,
        plate.law,
        priors=priors or None,
        draws=args.calibration_draws,
        fold_draws=args.fold_draws,
        seed=args.seed,
        progress=progress,
        plate_source=plate.label,
    )
    doc = report.to_dict()
    doc["calibration"]["scope"] = (
        f"all {len(scope)} runs (slip angles {sorted(set(scope['beta_level']))})"
        if args.scope == "all"
        else f"the {len(scope)} runs at slip angle β = 0; {len(runs) - len(scope)} runs at "
        "β ≠ 0 are not calibrated (--scope all)"
    )
    return doc, report


def apply_calibration(args: argparse.Namespace, runs: pd.DataFrame) -> dict:
    """``--calibration FILE`` on runs: coverage, width, MAE and bias of each quantity
    (:func:`soilstats.wheel.calibration.heldout.saved_calibration_scores`)."""
    from ..wheel.calibration import load_calibration  # deferred: arviz
    from ..wheel.calibration.heldout import saved_calibration_scores  # deferred: arviz

    cal = load_calibration(args.calibration)
    scores = saved_calibration_scores(cal, runs, seed=args.seed)
    return {"file": str(args.calibration)} | scores


def predict_mode(args: argparse.Namespace, priors: dict, overrides: dict) -> int:
    """--predict: the plate draws (unless a calibration carries them) and the prediction."""
    from ..wheel.soil import plate_draws  # deferred: scipy.stats

    if args.out:
        for name in PREDICT_OUTPUTS:
            output_path(Path(args.out), name, overwrite=args.overwrite)
    campaign, provenance = prepared(args)
    plate = None
    if not args.calibration:
        plate = plate_draws(
            campaign,
            soil=args.soil,
            law=args.law,
            kind=args.draws,
            n_draws=args.n_draws,
            seed=args.seed,
            progress=progress_enabled(args.progress),
        )
    return predict(args, provenance, plate, priors, overrides)


def predict(
    args: argparse.Namespace,
    provenance: Provenance,
    plate: PlateDraws | None,
    priors: dict,
    overrides: dict,
) -> int:
    """``--predict``: a rover team's own wheel."""
    from ..wheel import Wheel  # deferred: scipy.stats
    from ..wheel.calibration import load_calibration  # deferred: arviz
    from ..wheel.calibration.predict import CMU_DISCREPANCY, predict_own_wheel  # deferred: arviz
    from ..wheel.run_options import parse_slips  # deferred: scipy.stats

    geometry = overrides.get("*", {})
    if "radius_m" not in geometry or "width_m" not in geometry:
        raise InputError("--predict needs --wheel-radius R and --wheel-width B (m)")
    wheel = Wheel(
        radius_m=geometry["radius_m"],
        width_m=geometry["width_m"],
        shear_radius_m=geometry.get("shear_radius_m"),
        grouser_area_ratio=geometry.get("grouser_area_ratio", 1.0),
        name=args.wheel_type,
    )
    cal = load_calibration(args.calibration) if args.calibration else None
    result = predict_own_wheel(
        wheel,
        args.load,
        parse_slips(args.slips),
        calibration=cal,
        plate_draws=None if plate is None else plate.draws,
        law=None if plate is None else plate.law,
        priors=priors or None,
        discrepancy_prior=CMU_DISCREPANCY if args.discrepancy_prior == "cmu" else None,
        slip_angle_deg=args.slip_angle,
        pull_N=args.pull,
        n_draws=args.n_draws,
        seed=args.seed,
        plate_source="" if plate is None else plate.label,
    )
    document = result.to_dict()
    if args.out:
        from ..report.wheel_predict_pdf import write_report  # deferred: matplotlib

        folder = Path(args.out)
        write_json(folder / "wheel.json", document, provenance, overwrite=args.overwrite)
        write_csv(
            folder / "wheel_draws.csv",
            result.draws,
            provenance,
            overwrite=args.overwrite,
            float_format="%.6g",
        )
        _draws_netcdf(result.draws, folder / "wheel_draws.nc", args.overwrite)
        write_report(result, folder / "wheel.pdf", provenance=provenance, overwrite=args.overwrite)
        print(f"wrote {', '.join(str(folder / n) for n in PREDICT_OUTPUTS)}", file=sys.stderr)
    if args.json:
        print(
            json.dumps(
                json_safe(document | {"provenance": provenance.to_dict()}),
                indent=2,
                ensure_ascii=False,
            )
        )
    else:
        print(result.summary())
    return 0


def _draws_netcdf(draws: pd.DataFrame, path: Path, overwrite: bool) -> None:
    """The joint draws as netCDF: one variable per quantity over (draw, slip)."""
    import xarray as xr  # deferred: pandas


    target = output_path(path.parent, path.name, overwrite=overwrite)
    ds = xr.Dataset.from_dataframe(draws.set_index(["draw", "slip"]))
    buffer = io.BytesIO()
    ds.to_netcdf(buffer, engine="h5netcdf")  # in memory: no HDF5 handle on a file
    write_atomic(target, buffer.getvalue())


def command_defaults(
    args: argparse.Namespace, tables: dict, overrides: dict, wheels: dict
) -> dict[str, str]:
    """The analysis options left at their defaults, and every wheel geometry the user did not
    give (a missing shearing radius makes a wheel smooth: a grousered wheel's slip finding
    depends on it), for the JSON's ``"defaults"`` and page 1."""
    from ..wheel.run_options import geometry_defaults  # deferred: scipy.stats

    out = defaults_not_given(args)
    unused = set(PREDICT_OPTIONS) if not args.predict else set()
    if not args.calibrate:
        unused |= set(CALIBRATE_OPTIONS)
    out = {k: v for k, v in out.items() if k not in unused}
    return out | geometry_defaults(wheels, tables, overrides)
