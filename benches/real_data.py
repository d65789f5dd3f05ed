"""Every recording in ``../shared/data`` through the command line as a new user runs it — ``bmr import`` →
``bmr identify`` → ``bmr predict`` (→ ``bmr diagnose --model`` of that model where it is quick) with held-out runs
and bmr's defaults — next to the best reference figure for that data.

    python benches/real_data.py            # print the table
    python benches/real_data.py --record   # and record it as the ``real_data`` section of docs/results.md
    python benches/real_data.py --only feco_forc --only slac   # only these data sets (print only)
    python benches/real_data.py --diagnose-without-model   # every data set diagnosed as `bmr diagnose BUNDLE` does

The same chain runs in the tests (tests/python/real_data), which skip the data sets that are absent. References:
the measurement's own noise floor (FORC files: the white noise of the moment along each curve, from its second
differences), the single-valued baseline ``bmr predict`` reports, a hand-built least-squares model where one is
cheap to build here (the MR damper: a sum of play operators on displacement, fitted on the same training runs), or
the published figure (SLAC: diff_hysteresis, Roussel et al., PRL 2022).
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"


@dataclass(frozen=True)
class DataSet:
    """One data set's chain: its files, the declared columns, the runs held out, and what to compare with."""

    key: str
    folder: str
    label: str
    files: tuple[str, ...]
    import_args: tuple[str, ...]
    holdout: Callable[[list[str]], list[str]]  # run names -> the held-out ones
    diagnose: bool = False
    noise_floor: bool = False  # compare with the output's noise floor (FORC files)
    reference: str = ""  # a published or quoted reference figure
    reference_value: float | None = None
    forc_figure: str = ""  # docs/ file for the FORC diagram of the identified model (written with --record)

    def paths(self) -> list[Path]:
        return [DATA / self.folder / f for f in self.files]

    def present(self) -> bool:
        return all(p.is_file() for p in self.paths())


def _every_other(names: list[str]) -> list[str]:
    return names[1::2]


def _named(*held: str) -> Callable[[list[str]], list[str]]:
    return lambda names: [n for n in names if n in held]


DATASETS = (
    DataSet("slac", "slac-quad-4194", "SLAC quadrupole 4194, runs 7-8 held out",
            tuple(f"strplt.ru{k}" for k in range(3, 9)),
            ("--input", "MAIN:A", "--output", "BL:T", "--output-name", "integrated gradient", "--output-sigma",
             "sigBL"), _named("run7", "run8"),
            reference="diff_hysteresis (Roussel et al., PRL 2022), one history through runs 3-8", reference_value=0.74e-3),
    DataSet("mr_damper", "mr-damper-utfpr", "MR damper, A.1-A.3 identify, A.4 held out",
            tuple(f"ensaio.A.{k}.mat" for k in range(1, 5)), ("--input", "dist:mm", "--output", "forc:N"),
            _named("ensaio.A.4"), diagnose=True),
    DataSet("feco_forc", "forc-feco-nanowires", "FeCo nanowires, MicroMag FORCs (cgs), every other curve held out",
            ("hchb_forc",), ("--input", "Field", "--output", "Moment"), _every_other, noise_floor=True,
            forc_figure="fig_feco_forc_diagram.png"),
    DataSet("sediment_forc", "forc-marine-sediment", "Marine sediment, MicroMag FORCs (Hybrid SI), every other "
            "curve held out", ("MSM33-55-1_d330.forc",), ("--input", "Field", "--output", "Moment"), _every_other,
            noise_floor=True),
    DataSet("sediment_lakeshore", "forc-marine-sediment", "Marine sediment, Lake Shore FORC CSV, every other "
            "curve held out", ("B-9-3-85-87-FORC-1.5T.csv",), ("--input", "Field", "--output", "Moment"),
            _every_other, noise_floor=True),
    DataSet("steel_bh", "bh-loops-steel-ferrite", "M130-27s steel B(H), largest loop identifies, 2 smaller held out",
            ("H_M130_27s.mat", "B_M130_27s.mat"), ("--input", "HmeasT:A/m", "--output", "BmeasT:T"),
            _named("M130_27s-1", "M130_27s-2"), diagnose=True),
    DataSet("ferrite_bh", "bh-loops-steel-ferrite", "MnZn ferrite B(H), largest loop identifies, 3 smaller held out",
            ("H_MnZn_ferrite.mat", "B_MnZn_ferrite.mat"), ("--input", "HmeasT:A/m", "--output", "BmeasT:T"),
            _named("MnZn_ferrite-1", "MnZn_ferrite-2", "MnZn_ferrite-3"), diagnose=True),
)


@dataclass
class ChainResult:
    """What the chain did on one data set: each command's exit status and last error line, the held-out figures
    (output units) and the references."""

    key: str
    label: str
    unit: str = ""
    status: dict[str, int] = field(default_factory=dict)
    errors: dict[str, str] = field(default_factory=dict)
    runs: int = 0
    held_out: int = 0
    rms: float = float("nan")
    rms_pct_span: float = float("nan")
    baseline_rms: float = float("nan")
    noise_floor: float | None = None
    hand_lstsq_rms: float | None = None
    reference: str = ""
    reference_value: float | None = None
    extended_rms: float | None = None
    named: list[str] = field(default_factory=list)
    seconds: float = 0.0
    cpu_s: dict[str, float] = field(default_factory=dict)  # CPU seconds of each command (this process)

    @property
    def ok(self) -> bool:
        return bool(self.status) and all(s == 0 for s in self.status.values())

    def to_dict(self) -> dict[str, Any]:
        return {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in self.__dict__.items()}


def _cli(args: list[str]) -> tuple[int, str, str]:
    """``bmr ARGS`` in this process: exit status, standard output and standard error (a traceback is caught
    and becomes status 99 with its last line)."""
    from bmr.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(args)
        except SystemExit as exc:
            rc = int(exc.code or 0)
        except Exception as exc:  # noqa: BLE001 - a traceback is what the chain must never give
            return 99, out.getvalue(), f"traceback: {type(exc).__name__}: {exc}"
    return rc, out.getvalue(), err.getvalue()


def _play_lstsq(train: list[tuple[np.ndarray, np.ndarray]], test: tuple[np.ndarray, np.ndarray],
                count: int = 16) -> float:
    """Held-out RMS of a least-squares sum of ``count`` play operators (widths spread over the input span) plus a
    constant, fitted on ``train``: the hand-built reference of a Prandtl-Ishlinskii-type model."""
    u_all = np.concatenate([u for u, _ in train])
    widths = np.linspace(0.0, 0.5 * float(np.ptp(u_all)), count)

    def features(u: np.ndarray) -> np.ndarray:
        x = np.empty((u.size, count + 1))
        state = np.full(count, float(u[0]))
        for k, v in enumerate(u):
            state = np.clip(state, v - widths, v + widths)
            x[k, :count] = state
        x[:, count] = 1.0
        return x

    a = np.vstack([features(u) for u, _ in train])
    coef, *_ = np.linalg.lstsq(a, np.concatenate([y for _, y in train]), rcond=None)
    e = test[1] - features(test[0]) @ coef
    return float(np.sqrt(np.mean(e * e)))


def run_chain(ds: DataSet, workdir: Path, figures: bool = False, without_model: bool = False) -> ChainResult:
    """The chain on one data set in ``workdir`` (``figures``: also draw the data set's FORC diagram into docs/;
    ``without_model``: diagnose every data set as ``bmr diagnose BUNDLE`` does, on the model it makes itself)."""
    import bmr
    from bmr.data.signals import sample_noise

    res = ChainResult(ds.key, ds.label, reference=ds.reference, reference_value=ds.reference_value)
    t0 = time.perf_counter()
    names = [t.name for p in ds.paths() for t in bmr.read_tables(p)]
    if ds.key.endswith("_bh"):  # matrix columns: one run per loop, named after the joined files
        names = [f"{ds.files[0][2:-4]}-{k}" for k in range(1, 5)]
    held = ds.holdout(names)
    bundle, model, pred = workdir / "bundle", workdir / "model.json", workdir / "prediction.json"
    steps = [("import", ["import", *map(str, ds.paths()), *ds.import_args, "--holdout", ",".join(held), "-o",
                         str(bundle)]),
             ("identify", ["identify", str(bundle), "-o", str(model)]),
             ("predict", ["predict", str(model), str(bundle), "--json", str(pred)])]
    extended = workdir / "extended.json"
    if ds.diagnose or without_model:
        # The README's chain: the diagnosis extends the model identify chose (or, without it, its own).
        given = [] if without_model else ["--model", str(model)]
        steps.append(("diagnose", ["diagnose", str(bundle), *given, "--json", str(workdir / "diagnosis.json"),
                                   "--model-out", str(extended)]))
        steps.append(("predict extended", ["predict", str(extended), str(bundle), "--json",
                                           str(workdir / "extended_prediction.json")]))
    for step, args in steps:
        c0 = time.process_time()
        rc, _, err = _cli(args)
        res.cpu_s[step] = time.process_time() - c0
        res.status[step] = rc
        if rc != 0:
            res.errors[step] = err.strip().splitlines()[-1] if err.strip() else f"exit status {rc}"
            break
    res.seconds = time.perf_counter() - t0
    if not pred.is_file():
        return res
    if figures and ds.forc_figure:
        from bmr.report.forc_diagram import forc_diagram

        forc_diagram(bmr.Model.load(model), ROOT / "docs" / ds.forc_figure,
                     title=f"{ds.label.split(',')[0]}: identified density")
    p = json.loads(pred.read_text())
    total = p["total"]
    res.unit = p["output_unit"]
    res.rms, res.rms_pct_span, res.baseline_rms = total["rms"], total["rms_pct_span"], total["baseline_rms"]
    b = bmr.read_bundle(bundle)
    res.runs, res.held_out = len(b.runs), len(b.evaluation_runs())
    if ds.noise_floor:
        res.noise_floor = sample_noise([np.asarray(r.output, dtype=float) for r in b.runs])
    if ds.key == "mr_damper":
        train = [(r.input, r.output) for r in b.identification_runs()]
        [test] = [(r.input, r.output) for r in b.evaluation_runs()]
        res.hand_lstsq_rms = _play_lstsq(train, test)
    ext_pred = workdir / "extended_prediction.json"
    if ext_pred.is_file():
        res.extended_rms = json.loads(ext_pred.read_text())["total"]["rms"]
    diag = workdir / "diagnosis.json"
    if diag.is_file():
        d = json.loads(diag.read_text())
        res.named = [str(e["name"]) for e in d.get("effects", []) if isinstance(e, dict) and "name" in e]
    return res


def run_all(datasets: tuple[DataSet, ...] = DATASETS, figures: bool = False, without_model: bool = False
            ) -> list[ChainResult]:
    out = []
    for ds in datasets:
        if not ds.present():
            print(f"{ds.key}: skipped, {DATA / ds.folder} is absent", file=sys.stderr)
            continue
        with tempfile.TemporaryDirectory() as tmp:
            out.append(run_chain(ds, Path(tmp), figures, without_model))
    return out


def render(values: dict[str, Any]) -> str:
    """The docs/results.md table."""
    diagnose = "diagnose --model-out" if values.get("without_model") else "diagnose --model model.json --model-out"
    rows = ["| data set (held out) | chain | held-out RMS | % of span | single-valued baseline | extended model "
            f"(`{diagnose}`) | reference |", "|---|---|---|---|---|---|---|"]
    for r in values["results"]:
        u = r["unit"]
        chain = "ok" if all(s == 0 for s in r["status"].values()) else "; ".join(
            f"{k}: {v}" for k, v in r["errors"].items())
        refs = []
        if r.get("noise_floor"):
            refs.append(f"noise floor {r['noise_floor']:.3g} {u} (RMS {r['rms'] / r['noise_floor']:.2g}× it)")
        if r.get("hand_lstsq_rms"):
            refs.append(f"16 play operators, least squares: {r['hand_lstsq_rms']:.3g} {u}")
        if r.get("reference_value"):
            refs.append(f"{r['reference']}: {r['reference_value']:.3g} {u}")
        if r.get("named"):
            refs.append("diagnosis named " + ", ".join(r["named"]))
        fmt = (lambda x: "—" if x is None else f"{x:.3g} {u}")
        rows.append(f"| {r['label']} ({r['held_out']} of {r['runs']} runs) | {chain} | {fmt(r['rms'])} | "
                    f"{'—' if r['rms_pct_span'] is None else format(r['rms_pct_span'], '.3g')} | "
                    f"{fmt(r['baseline_rms'])} | {fmt(r.get('extended_rms'))} | {'; '.join(refs) or '—'} |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--record", action="store_true", help="record the figures as docs/results.md's real_data section "
                    "and draw the FORC diagrams into docs/")
    ap.add_argument("--only", action="append", choices=[d.key for d in DATASETS], metavar="NAME",
                    help="run only this data set (repeatable; one of %(choices)s); not with --record")
    ap.add_argument("--diagnose-without-model", action="store_true",
                    help="diagnose every data set without --model (on the model `bmr diagnose` makes itself) and "
                         "predict its extended model; not with --record")
    args = ap.parse_args(argv)
    if (args.only or args.diagnose_without_model) and args.record:
        ap.error("--record measures the README's chain on every data set: drop --only and --diagnose-without-model")
    chosen = tuple(d for d in DATASETS if not args.only or d.key in args.only)
    results = run_all(chosen, figures=args.record, without_model=args.diagnose_without_model)
    values = {"results": [r.to_dict() for r in results]}
    print(render({**values, "without_model": args.diagnose_without_model}))
    for r in results:
        print(f"{r.key}: " + ", ".join(f"{k} {v:.1f} CPU-s" for k, v in r.cpu_s.items()), file=sys.stderr)
    if args.record:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from measurements import record

        record("real_data", "python benches/real_data.py --record", values)
    return 0 if all(r.ok for r in results) else 1


if __name__ == "__main__":
    raise SystemExit(main())
