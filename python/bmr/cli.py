"""The ``bmr`` command line: ``bmr demo | simulate | import | identify | predict | diagnose | export``.

Each subcommand's work lives in the module that owns the capability; this file only parses arguments.
"""
from __future__ import annotations

import argparse
import sys
from typing import Sequence

from bmr._core import PRESETS, BmrError
from bmr.data.formats import FORMATS
from bmr.identification.lstsq import DEFAULT_GRID, DENSITIES, GRIDS
from bmr.simulation.excitation import SEPARATING_RUNS

BUNDLE_HELP = "bundle folder (manifest.json plus one CSV or Parquet file per run; see `bmr simulate`)"


def _parser() -> argparse.ArgumentParser:
    from bmr import __version__

    p = argparse.ArgumentParser(prog="bmr", description="Accurate control of hysteretic actuators: CBH hysteresis, "
                                "exact inverse, friction compensation, simulation, identification and diagnosis.")
    p.add_argument("--version", action="version", version=f"bmr {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    presets = tuple(PRESETS)
    preset_help = f"virtual actuator preset, one of {', '.join(presets)} (default: bmr2013)"
    seed_help = "seed of the simulated sensor noise; the same seed gives the same bits (default: 0)"

    d = sub.add_parser("demo", help="run the paper's experiments on the virtual actuator and write a report")
    d.add_argument("--out", default="bmr-demo", help="output folder (default: bmr-demo)")
    d.add_argument("--preset", default="bmr2013", choices=presets, metavar="PRESET", help=preset_help)
    d.add_argument("--seed", type=int, default=0, help=seed_help)
    d.add_argument("--quick", action="store_true", help="shorter runs (about a tenth of the full programme)")

    s = sub.add_parser("simulate", help="write the paper's experiment set from the virtual actuator as a bundle")
    s.add_argument("--preset", default="bmr2013", choices=presets, metavar="PRESET", help=preset_help)
    s.add_argument("--effect", action="append", default=[], metavar="NAME[:key=value,...]",
                   help="switch on an effect of the virtual actuator (repeatable; names and parameters in "
                        "bmr.effect_parameters())")
    s.add_argument("--override", action="append", default=[], metavar="GROUP.PARAM=VALUE",
                   help="change a physical parameter of the preset (repeatable; names in bmr.ACTUATOR_PARAMETERS)")
    s.add_argument("--seed", type=int, default=0, help=seed_help)
    s.add_argument("--quick", action="store_true", help="shorter runs")
    s.add_argument("--separate", action="append", default=[], choices=tuple(SEPARATING_RUNS), metavar="KIND",
                   help="append a run that separates effects the set cannot tell apart (repeatable; what "
                        "`bmr diagnose` asks for): " + "; ".join(f"{k}: {v[0]}" for k, v in SEPARATING_RUNS.items()))
    s.add_argument("--forc-reversals", type=int, default=None, metavar="N",
                   help="reversals per first-order family (default 21, quick 11): finer tables")
    s.add_argument("--format", choices=("csv", "parquet"), default="csv", help="run file format (default: csv)")
    s.add_argument("-o", "--out", required=True, help="bundle folder to write")

    m = sub.add_parser("import", help="turn raw lab logs into a bundle (declared input/output, protocol, roles)",
                       description="Read lab logs (CSV, Parquet, TDMS, MAT, spreadsheets, dSPACE ControlDesk captures, "
                       "tab-separated analyzer exports, SLAC magnetic-measurement tables, MicroMag and Lake Shore "
                       "magnetometer exports) into a bundle. Columns "
                       "are COL, COL:UNIT (the unit the bundle stores; converted from the unit the file states) "
                       "or COL:SOURCE:UNIT (for files that state no unit).")
    m.add_argument("files", nargs="+", help="log files (every table holding the declared columns is a run)")
    m.add_argument("--input", required=True, metavar="COL[:UNIT]", help="the device's input column")
    m.add_argument("--output", required=True, metavar="COL[:UNIT]", help="the device's output column")
    m.add_argument("--angle", metavar="COL[:UNIT]",
                   help="rotor angle column (optional; stored in rad, so a unit given here is the file's)")
    m.add_argument("--time", metavar="COL[:UNIT]",
                   help="time column (default: the format's time axis or a column named time/t; stored in s, so a unit "
                        "given here is the file's)")
    m.add_argument("--output-sigma", metavar="COL[:UNIT]",
                   help="per-sample standard uncertainty of the output (optional)")
    m.add_argument("--input-name", help="name of the input quantity (default from its unit, e.g. V -> voltage)")
    m.add_argument("--output-name", help="name of the output quantity (e.g. 'integrated gradient')")
    m.add_argument("--protocol", choices=("forc-ascending", "forc-descending", "major-loop", "any"),
                   default="any", help="what the identification runs follow; checked with their reversals "
                   "(default: any)")
    m.add_argument("--holdout", action="append", default=[], metavar="RUN[,RUN...]",
                   help="runs (or files) held out for evaluation; the others are for identification")
    m.add_argument("--holdout-tail", type=float, metavar="SHARE",
                   help="hold out the last SHARE (0-1) of every identification run as its own evaluation run "
                        "('<run>-tail', recorded right after the head): for a recording that is one long run")
    m.add_argument("--format", choices=FORMATS,
                   help="force a reader (default: from extension and content)")
    m.add_argument("--device", help="device name stored in the bundle")
    m.add_argument("--sample-rate", type=float, metavar="HZ", help="time from the sample index for files without one")
    m.add_argument("--deadband", type=float, metavar="X", help="reversal dead-band in input units "
                   "(default: 1 %% of the input span or 10x its sample noise)")
    m.add_argument("--keep-edges", action="store_true", help="keep an idle hold at a run's start and a command "
                   "jump at its end (default: left out of the bundle and named in the summary)")
    m.add_argument("--file-format", choices=("csv", "parquet"), default="csv", help="bundle run files (default csv)")
    m.add_argument("-o", "--out", required=True, help="bundle folder to write (new or empty)")

    i = sub.add_parser("identify", help="identify friction and CBH tables from a bundle")
    i.add_argument("bundle", help=BUNDLE_HELP)
    i.add_argument("--method", choices=("auto", "forc", "lstsq", "both"), default="auto",
                   help="hysteresis tables from first-order reversal curves (forc, the paper's method), by least "
                        "squares from any excitation (lstsq), or both, keeping the one with the lower held-out "
                        "error on the evaluation runs or, without any, on first-order curves held out in two "
                        "folds (auto, the default, also when one of them is impossible)")
    i.add_argument("--intervals", type=int, default=None, metavar="N",
                   help="least-squares table: grid intervals over the input range (default: chosen by "
                        "cross-validation over time blocks of the training runs)")
    i.add_argument("--smoothing", type=float, default=None, metavar="S",
                   help="least-squares table: weight of the density's smoothness (default: chosen by "
                        "cross-validation over time blocks of the training runs)")
    i.add_argument("--grid", choices=GRIDS, default=DEFAULT_GRID,
                   help="least-squares table: nodes evenly spaced (uniform) or finer where the branches switch "
                        "and the runs reverse (adaptive); auto (the default): adaptive for a family of "
                        "first-order reversal curves, uniform otherwise")
    i.add_argument("--density", choices=DENSITIES, default="auto",
                   help="least-squares table: a Preisach density (nonnegative: loops run counter-clockwise, exact "
                        "inverse) or masses free in sign (signed: loops that run clockwise, the output leading the "
                        "input, or negative density regions); auto (the default): signed when the training loops run "
                        "clockwise (no compensator), or when a family of first-order reversal curves is predicted "
                        "clearly better by it (the compensator inverts the nonnegative table beside it)")
    i.add_argument("-o", "--out", required=True,
                   help="model file to write (bmr-model/2 JSON: tables, friction, the bundle's quantities and units)")

    g = sub.add_parser("diagnose", help="find what the model gets wrong in a bundle and name the cause",
                       description="Diagnose one bundle (report on the terminal, --json, --report), or many at "
                                   "once on Dask (one row per bundle in a Parquet table, --out).")
    g.add_argument("bundle", nargs="+", help=BUNDLE_HELP + "; several bundles are diagnosed in parallel on Dask "
                   "(pip install 'bmr[dask]')")
    g.add_argument("--model", help="model file (default: the paper's model from the bundle's first-order "
                   "runs; a bundle without any gets the tables `bmr identify` chooses, with the paper's friction)")
    g.add_argument("--folds", type=int, default=5,
                   help="blocked folds: each evaluation run is cut into this many time blocks, each held out in "
                        "turn (default: 5)")
    g.add_argument("--seed", type=int, default=0, help="seed of the bootstrap interval of the fold gains (default: 0)")
    g.add_argument("--json", dest="json_out", help="write the bmr-diagnosis/2 JSON here")
    g.add_argument("--report", help="write an HTML report here (one bundle)")
    g.add_argument("--model-out", metavar="OUT.json", help="write the extended model file here (one bundle): the "
                   "model with what the diagnosis found and each stage's closed-loop verdict, for "
                   "bmr.Compensator.from_model and bmr export")
    g.add_argument("--out", help="several bundles: the Parquet table of results (default: bmr-diagnoses.parquet)")
    g.add_argument("--scheduler", help="several bundles: address of a running Dask scheduler (tcp://host:8786); "
                                       "default: a local cluster on this machine")
    g.add_argument("--workers", type=int, help="several bundles: worker processes of the local cluster (default: "
                                               "one per core; 0: no Dask, one after the other here)")

    r = sub.add_parser("predict", help="predict a bundle's held-out runs with a model: RMS and max error per run")
    r.add_argument("model", help="model file (bmr-model JSON, from `bmr identify`)")
    r.add_argument("bundle", help=BUNDLE_HELP)
    r.add_argument("--runs", action="append", default=[], metavar="RUN[,RUN...]",
                   help="runs to predict (default: the bundle's evaluation runs)")
    r.add_argument("--offset", choices=("run", "model", "first", "shrunk"), default="run",
                   help="each run's output offset: its own, fitted on its scored samples and shrunk towards the "
                        "model's by how much the training runs' offsets spread, with a gain where their gains spread "
                        "(run, the default); the model's (model); from the run's leading --calibration samples "
                        "(first; they are then not scored); or that shrunk towards the model's (shrunk)")
    r.add_argument("--calibration", type=int, metavar="N",
                   help="leading samples of each run used to calibrate it, not scored (default: 1 with --offset "
                        "first, else 0)")
    r.add_argument("--initial", choices=("negative", "positive", "estimate", "continue"), default="negative",
                   help="each run's initial state: a saturation, estimated from its calibration samples (the "
                        "whole run without any), or continuing the bundle's measurement history: the state the "
                        "model holds after every earlier run's input, from the history's start (default: negative)")
    r.add_argument("--evaluate", choices=("known", "all"), default="known",
                   help="score from where the run's state is known (after both saturation ends) or all samples "
                        "(default: known)")
    r.add_argument("--out-of-range", choices=("clamp", "extrapolate"), default="clamp",
                   help="inputs beyond the model's range: held at its ends, or continued along the major branches "
                        "(default: clamp)")
    r.add_argument("--json", dest="json_out", help="write the bmr-prediction/1 JSON here")
    r.add_argument("--figure", help="write a PNG figure (measured vs predicted vs input; residual) here")

    x = sub.add_parser("export", help="write a model's compensator as firmware source (Rust no_std or C)")
    x.add_argument("model", help="model file (bmr-model JSON, e.g. from `bmr diagnose --model-out`)")
    lang = x.add_mutually_exclusive_group(required=True)
    lang.add_argument("--rust", metavar="OUT.rs", help="write static tables and model::compensator(dt_s) for the "
                      "no_std crate")
    lang.add_argument("--c", metavar="OUT.h", help="write C arrays and <prefix>_model for bmr_compensator_init "
                      "(include/bmr.h, cargo feature ffi)")
    x.add_argument("--stages", default=None, help="extensions to compensate: 'all' or a comma-separated list "
                   "(default: those the closed-loop check did not find harmful)")
    x.add_argument("--prefix", default="bmr", help="C name prefix of the exported model (default: bmr)")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run a subcommand. Problems with the user's data, arguments or files end with exit status 2 and one line
    naming the file and the problem; a bug in bmr with status 1 and one line saying so; never a traceback."""
    args = _parser().parse_args(argv)
    try:
        if args.command == "demo":
            from bmr.demo import run_cli
        elif args.command == "simulate":
            from bmr.simulation.excitation import run_cli
        elif args.command == "import":
            from bmr.data.importing import run_cli
        elif args.command == "identify":
            from bmr.identification.procedure import run_cli
        elif args.command == "predict":
            from bmr.identification.prediction import run_cli
        elif args.command == "export":
            from bmr.identification.model import run_export_cli as run_cli
        elif args.command == "diagnose" and (len(args.bundle) > 1 or args.out or args.scheduler
                                             or args.workers is not None):
            if args.json_out or args.report or args.model_out:
                raise BmrError("--json, --report and --model-out describe one bundle; for several, the table goes "
                               "to --out")
            from bmr.diagnosis.many import run_cli
        else:
            args.bundle = args.bundle[0]
            from bmr.diagnosis.procedure import run_cli
        return int(run_cli(args) or 0)
    except BmrError as exc:
        print(f"bmr {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        # A file the command had to read or write (the helpers name theirs in a BmrError; this is the rest).
        where = f"{exc.filename!r}: " if exc.filename else ""
        print(f"bmr {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"bmr {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - a bug still ends in one line, not a traceback
        print(f"bmr {args.command}: internal error (a bug in bmr; please report it with the command line): "
              f"{type(exc).__name__}: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
