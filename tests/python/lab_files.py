"""Writers of lab files in the layouts instruments produce (for reader tests), and a piezo-like device to fill them:
a Preisach plant written independently of bmr (``preisach_plant``) driven between 0 and 100 V, read out in µm with
sensor noise, switching that continues briefly after each reversal, and an unknown start state."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from preisach_plant import PreisachPlant

V_MAX = 100.0


# ------------------------------------------------------------------------------------------ instrument layouts
def write_controldesk(path: Path, var: str, axes: Sequence[np.ndarray],
                      channels: Sequence[tuple[str, str, np.ndarray, str, int]], *, v73: bool = False) -> Path:
    """A dSPACE ControlDesk capture: ``var.X(k)`` time axes, ``var.Y(k)`` channels ``(name, path, data, unit,
    x index)``, as MATLAB struct arrays with 1×N data rows (what ``save -v7`` of a capture holds; ``v73``: what
    ``save -v7.3`` holds)."""
    from scipy.io import savemat

    if v73:
        xs = [{"Name": "Time", "Type": "Xaxis", "Data": np.asarray(t, float).reshape(1, -1), "Unit": "s"} for t in axes]
        ys = [{"Name": name, "Type": "Signal", "Path": where, "Data": np.asarray(data, float).reshape(1, -1),
               "Unit": unit, "XIndex": float(xi)} for name, where, data, unit, xi in channels]
        return write_mat_v73(path, {var: {"X": xs, "Y": ys, "Description": "piezo stack, FORC protocol",
                                          "Capture": "trace 1", "RTProgram": "piezo_rig.sdf"}})
    x = np.zeros((1, len(axes)), dtype=[("Name", "O"), ("Type", "O"), ("Data", "O"), ("Unit", "O")])
    for k, t in enumerate(axes):
        x[0, k] = ("Time", "Xaxis", np.asarray(t, float).reshape(1, -1), "s")
    y = np.zeros((1, len(channels)), dtype=[("Name", "O"), ("Type", "O"), ("Path", "O"), ("Data", "O"),
                                            ("Unit", "O"), ("XIndex", "O")])
    for k, (name, where, data, unit, xi) in enumerate(channels):
        y[0, k] = (name, "Signal", where, np.asarray(data, float).reshape(1, -1), unit, float(xi))
    savemat(path, {var: {"X": x, "Y": y, "Description": "piezo stack, FORC protocol", "Capture": "trace 1",
                         "RTProgram": "piezo_rig.sdf"}})
    return path


V73_HEADER = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Nov 23 2026 HDF5 schema 1.00 ."


def write_mat_v73(path: Path, variables: dict) -> Path:
    """A MATLAB v7.3 MAT file as ``save -v7.3`` lays it out: an HDF5 file behind a 512-byte MATLAB header, each
    variable a dataset with its ``MATLAB_class`` stored transposed (column-major), text as UTF-16 code units, a
    struct a group of its fields, a struct array (a list of dicts) a group whose fields are arrays of references
    to the elements' values under ``#refs#``."""
    import h5py

    refs = {"n": 0}

    def put(group, name: str, value) -> None:
        if isinstance(value, dict):
            g = group.create_group(name)
            g.attrs["MATLAB_class"] = np.bytes_("struct")
            for k, v in value.items():
                put(g, k, v)
        elif isinstance(value, list):  # a 1×n struct array
            g = group.create_group(name)
            g.attrs["MATLAB_class"] = np.bytes_("struct")
            pool = group.file.require_group("#refs#")
            for field in value[0]:
                targets = []
                for element in value:
                    key = f"r{refs['n']}"
                    refs["n"] += 1
                    put(pool, key, element[field])
                    targets.append(pool[key].ref)
                g.create_dataset(field, data=np.array(targets, dtype=h5py.ref_dtype).reshape(-1, 1))
        elif isinstance(value, str):
            d = group.create_dataset(name, data=np.array([ord(c) for c in value], dtype=np.uint16).reshape(-1, 1))
            d.attrs["MATLAB_class"] = np.bytes_("char")
            d.attrs["MATLAB_int_decode"] = np.int32(2)
        else:
            arr = np.atleast_2d(np.asarray(value, dtype=float))
            d = group.create_dataset(name, data=arr.T)
            d.attrs["MATLAB_class"] = np.bytes_("double")

    with h5py.File(path, "w", userblock_size=512) as f:
        for name, value in variables.items():
            put(f, name, value)
    with open(path, "r+b") as fh:  # MATLAB's header in the user block: text, then version 0x0200 and 'IM'
        fh.write(V73_HEADER.ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02IM")
    return path


def write_aixacct(path: Path, tables: Sequence[tuple[dict[str, str], Sequence[str], np.ndarray]], *,
                  bracket_units: bool = False) -> Path:
    """An analyzer ASCII export: a banner and shared metadata, then per measurement a ``Table k`` title, its
    metadata lines, a tab-separated header of ``name unit`` (or ``name [unit]``) and rows of numbers."""
    lines = ["DynamicHysteresisResult", "SampleName: C12", "TfaVersion: 3.1", ""]
    for k, (meta, header, rows) in enumerate(tables):
        lines.append(f"Table {k + 1}")
        lines += [f"{key}: {value}" for key, value in meta.items()]
        if bracket_units:
            header = [f"{h.rsplit(' ', 1)[0]} [{h.rsplit(' ', 1)[1].replace('_per_', '/')}]" for h in header]
        lines.append("\t".join(header))
        lines += ["\t".join(f"{v:.6e}" for v in row) for row in rows]
        lines.append("")
    path.write_text("\n".join(lines), encoding="cp1252")
    return path


def write_micromag(path: Path, curves: Sequence[tuple[np.ndarray, np.ndarray]], *, h_cal: float,
                   m_cal: Sequence[float], system: str = "cgs", column_header: bool = False) -> Path:
    """A MicroMag 2900/3900 FORC export: header lines, optionally a column header and a units line (Latin-1
    ``²``), then per curve a one-point segment at the calibration field and the curve, blank-line separated, CRLF."""
    units = {"cgs": ("Oe", "emu"), "SI": ("A/m", "Am\u00b2"), "Hybrid SI": ("T", "Am\u00b2")}[system]
    lines = ["MicroMag 2900/3900 Data File (Series 0015)", "First-order reversal curves", "Configuration   :  VSM",
             f"Units of measure:  {system}", "Temperature in  :  Kelvin", "01/22/2015  17:35", '"test sample"', "",
             "Averaging time = +1.000000E-01", f"HCal           = {h_cal:+.6E}", f"NCrv           = {len(curves)}",
             ""]
    if column_header:
        lines += ["Field,Moment", f"({units[0]}),({units[1]})", ""]
    for (h, m), mc in zip(curves, m_cal):
        lines += [f"{h_cal:+.6E},{mc:+.6E}", ""]
        lines += [f"{a:+.6E},{b:+.6E}" for a, b in zip(h, m)] + [""]
    lines.append("MicroMag 2900/3900 Data File ends")
    path.write_bytes("\r\n".join(lines).encode("latin-1"))
    return path


def _micromag_header(kind: str, settings: list[tuple[str, float]], ndata: int) -> list[str]:
    """The header of a MicroMag 2900/3900 export as the instrument writes it (the real FeCo file's layout)."""
    lines = ["MicroMag 2900/3900 Data File (Series 0015)", kind, "Configuration   :  VSM", "Hardware version:  0004",
             "Software version:  09/27/2005 D", "Units of measure:  cgs", "Temperature in  :  Kelvin",
             "03/14/2016  09:12", '"CoFe interacting particles, OOP"', ""]
    lines += [f"{k:<15}= {v:+.6E}" for k, v in settings] + [""]
    lines += ["Field range    = +1.000000E+04", "Moment range   = +2.000000E-03", "Temperature    = N/A",
              "Orientation    =  0.000000E+00", "Slope corr.    = N/A", "Saturation     = N/A",
              f"NData          = {ndata}", ""]
    return lines


def write_micromag_forc_measurement(path: Path, curves: Sequence[tuple[np.ndarray, np.ndarray]],
                                    calibration: Sequence[tuple[float, float]],
                                    settings: Sequence[tuple[str, float]]) -> Path:
    """A MicroMag FORC file as the instrument writes it: the full header (``HCal``, ``HSat``, ``NCrv``, pauses ...;
    no column header, like the FeCo file), then per curve a one-point segment at the calibration field (as measured:
    its field reading too) and the curve, blank-line separated, cgs, CRLF."""
    rows = sum(1 + len(h) for h, _ in curves)
    lines = _micromag_header("First-order reversal curves", [*settings, ("NCrv", float(len(curves)))], rows)
    for (h, m), (hc, mc) in zip(curves, calibration):
        lines += [f"{hc:+.6E},{mc:+.6E}", ""]
        lines += [f"{a:+.6E},{b:+.6E}" for a, b in zip(h, m)] + [""]
    lines.append("MicroMag 2900/3900 Data File ends")
    path.write_bytes("\r\n".join(lines).encode("latin-1"))
    return path


def write_micromag_hysteresis(path: Path, branches: Sequence[tuple[np.ndarray, np.ndarray]],
                              settings: Sequence[tuple[str, float]]) -> Path:
    """A MicroMag hysteresis-loop export: the header, then the loop's branches as blank-line separated segments
    (from the maximum field down, then up), cgs, CRLF."""
    lines = _micromag_header("Hysteresis loop", list(settings), sum(len(h) for h, _ in branches))
    for h, m in branches:
        lines += [f"{a:+.6E},{b:+.6E}" for a, b in zip(h, m)] + [""]
    lines.append("MicroMag 2900/3900 Data File ends")
    path.write_bytes("\r\n".join(lines).encode("latin-1"))
    return path


def write_lakeshore(path: Path, curves: Sequence[tuple[np.ndarray, np.ndarray]], *, h_cal: float,
                    m_cal: Sequence[float], dt: float = 0.1) -> Path:
    """A Lake Shore VSM FORC export: settings, ``##DATA TABLE``, a Latin-1 header with ``µ0H`` and ``A·m²``, rows
    of ``Step,Iteration,Segment,Field,Moment,Time Stamp,Field Status,Moment Status`` in blank-line separated
    segments (calibration point, curve, ...), CRLF."""
    lines = ["#FIELD CONFIGURATIONS", "Magnet: EM4-CSB", "#FORC MEASUREMENT", "Saturation field: 1.5 T",
             "Averaging time: 0.1 s", "#DATA: 1", "##DATA TABLE Moment (m) [A\u00b7m\u00b2] vs Field (\u00b50H) [T]",
             "Step,Iteration,Segment,Field (\u00b50H) [T],Moment (m) [A\u00b7m\u00b2],Time Stamp [s],Field Status,"
             "Moment (m) Status"]
    t, seg = 0.0, 0
    for (h, m), mc in zip(curves, m_cal):
        for hs, ms in ((np.array([h_cal]), np.array([mc])), (h, m)):
            for a, b in zip(hs, ms):
                lines.append(f"1,0,{seg},{float(a)!r},{float(b)!r},{t:.2f},GOOD,GOOD")
                t += dt
            lines.append("")
            seg += 1
    path.write_bytes("\r\n".join(lines).encode("latin-1"))
    return path


def write_slac(folder: Path, run: int, current: np.ndarray, bl: np.ndarray, *, t: np.ndarray | None = None,
               comment: str = "minor loop") -> tuple[Path, Path]:
    """``strdat.ru<run>`` and ``strplt.ru<run>`` in the SLAC magnetic-measurement layout."""
    n = current.size
    sig_i = np.full(n, 3e-4)
    sig_b = np.full(n, 1.2e-5)
    tf = np.where(current > 0, bl / np.maximum(current, 1e-9), 0.0)
    th = np.full(n, 45.53)
    head = ["SLAC Magnetic Measurements", "Date: 11-11-2021", "Time: 14:53:27", "", "Project: LCLS-II",
            "Magnet Type: Quad", "Magnet Name: 4194", "Serial Number: ", f"Run Number: {run}",
            "Measurement Device: 1DQB26", "Operator: sda", f"Comment: {comment}", "Test Currents for MAIN (A): ",
            "      " + "  ".join(f"{c:8.2f}" for c in current), "", "", "",
            "                                 Integrated Gradient (Quadrupole) ", "",
            "     MAIN   +/- sigma         BL         sigBL           TF        sigTF         THsp       sigTHsp   ",
            "            (A)                     (T)                       (T/A)                     (deg)      ",
            " ------------+----------  -----------+-----------   ------------+------------  -----------+---------"]
    rows = [f"  {a:10.4f} {b:10.4f} {c:12.6f} {d:11.6f} {e:14.6f} {f:11.6f} {g:11.4f} {h:9.4f}  "
            for a, b, c, d, e, f, g, h in zip(current, sig_i, bl, sig_b, tf, np.zeros(n), th, np.full(n, 1e-4))]
    dat = folder / f"strdat.ru{run}"
    dat.write_text("\n".join(head + rows) + "\n")
    t = np.arange(n) * 2.9 if t is None else t
    plt = ["  Time       MAIN  +/- sigma         BL    +/-   sigBL         TF    +/-  sigTF      THsp  +/-sigThsp "]
    plt += [f"{a:6.2f}  {b:10.7f}  {c:9.7f}  {d:10.7f}  {e:10.7f}  {f:10.8f}  {g:.6e}  {h:8.4f}  {i:7.4f}  "
            for a, b, c, d, e, f, g, h, i in zip(t, current, sig_i, bl, sig_b, tf, np.zeros(n), th, np.full(n, 1e-4))]
    pl = folder / f"strplt.ru{run}"
    pl.write_text("\n".join(plt) + "\n")
    return dat, pl


# ------------------------------------------------------------------------------------------ a piezo-like device
class Piezo:
    """Drive voltage 0..100 V -> displacement 0..~30 µm: a Preisach plant (``n`` thresholds) whose output keeps
    switching for a few samples after each reversal (a first-order lag of ``lag`` samples on the switched part),
    read with white noise of ``noise_um``. The state starts at an arbitrary remanence (``start_v``)."""

    def __init__(self, n: int = 80, noise_um: float = 0.01, lag: float = 3.0, seed: int = 0,
                 start_v: float = 62.0):
        self.plant = PreisachPlant(n, scale=15.0)
        self.plant.step(1.0)
        self.plant.step(2 * start_v / V_MAX - 1.0)
        self.noise = noise_um
        self.rng = np.random.default_rng(seed)
        self.a = 1.0 / (1.0 + lag)
        self.state = None

    def run(self, volts: np.ndarray) -> np.ndarray:
        raw = self.plant.run(2 * np.asarray(volts) / V_MAX - 1.0) + 15.0
        out = np.empty_like(raw)
        s = raw[0] if self.state is None else self.state
        for k, x in enumerate(raw):
            s += self.a * (x - s)
            out[k] = s
        self.state = s
        return out + self.noise * self.rng.standard_normal(raw.size)


def ramp(points: Sequence[float], volts_per_sample: float = 0.5) -> np.ndarray:
    out = [np.array([points[0]], float)]
    for a, b in zip(points[:-1], points[1:]):
        n = max(2, int(abs(b - a) / volts_per_sample))
        out.append(np.linspace(a, b, n + 1)[1:])
    return np.concatenate(out)


def descending_forc_drive(count: int = 12) -> np.ndarray:
    """The piezo FORC protocol: from 0 V rise to growing maxima, each followed by the fall back to 0 V."""
    points = [0.0]
    for m in np.linspace(V_MAX / count, V_MAX, count):
        points += [float(m), 0.0]
    return ramp(points)


def multi_reversal_drive() -> np.ndarray:
    """A held-out excitation: nested reversals inside the range, after a first excursion to the top."""
    return ramp([0.0, 100.0, 10.0, 85.0, 25.0, 70.0, 40.0, 95.0, 5.0, 60.0, 30.0])
