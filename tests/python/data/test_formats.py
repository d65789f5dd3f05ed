"""Instrument readers, each on files written in its layout: dSPACE ControlDesk captures, analyzer exports (tab-
separated tables with units), SLAC magnetic-measurement tables; plus unit-bearing CSV/TDMS headers and the errors
for files that are empty, truncated or of another format."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import bmr
from bmr.data.formats import read_tables
from lab_files import (V73_HEADER, write_aixacct, write_controldesk, write_lakeshore, write_mat_v73,
                       write_micromag, write_slac)
from preisach_plant import PreisachPlant

N = 300
T = np.arange(N) * 1e-3
VOLTS = 50.0 + 50.0 * np.sin(2 * np.pi * 3 * T)
MICRONS = 0.3 * VOLTS


# ------------------------------------------------------------------------------------------------ ControlDesk
def test_controldesk_capture_channels_by_name_path_and_tail(tmp_path):
    p = write_controldesk(tmp_path / "forc_01.mat", "forc_01", [T], [
        ("Model Root/Amp/Vout", "Model Root/Amp", VOLTS, "V", 1),
        ("x_um", "Model Root/Sensor", MICRONS, "", 1)])
    [t] = read_tables(p)  # detected from the .mat content
    assert t.name == "forc_01" and t.time_column == "time" and t.n_samples == N
    np.testing.assert_array_equal(t.columns["time"], T)
    assert t.column("Vout")[0] == "Model Root/Amp/Vout"  # the last part of the signal path
    assert t.column("Model Root/Sensor/x_um")[0] == "x_um"  # Path/Name
    np.testing.assert_array_equal(t.column("X_UM")[1], MICRONS)
    assert t.unit_of("Model Root/Amp/Vout") == "V" and t.unit_of("x_um") is None and t.unit_of("time") == "s"
    assert t.meta["RTProgram"] == "piezo_rig.sdf"


def test_controldesk_quoted_paths_and_control_bytes_are_names_a_user_types(tmp_path):
    # Real captures quote every path segment, and a block label that held a line break keeps a 0x1A byte.
    p = write_controldesk(tmp_path / "no_lp_20.mat", "no_lp_20", [T], [
        ('"Model Root"/"P\x1adrag"/"In1"', '"Model Root"/"P\x1adrag"', VOLTS, "V", 1),
        ('"Model Root"/"Mling"/"Out1"', '"Model Root"/"Mling"', MICRONS, "V", 1)])
    [t] = read_tables(p)
    assert set(t.columns) == {"time", "Model Root/Pdrag/In1", "Model Root/Mling/Out1"}
    for typed in ("Pdrag", "Model Root/Pdrag/In1", "pdrag", "In1"):
        assert t.column(typed)[0] == "Model Root/Pdrag/In1", typed
    np.testing.assert_array_equal(t.column("Mling")[1], MICRONS)
    with pytest.raises(bmr.BundleError) as err:
        t.column("Pdrug", "input")
    # The names listed are the ones a user can type: no quotes, no control bytes.
    assert "Model Root/Pdrag/In1, Model Root/Mling/Out1" in str(err.value) and "\x1a" not in str(err.value)
    assert '"' not in str(err.value).split("columns:")[1]
    # Input and output in the same unit (V): each quantity is named by its column.
    result = bmr.import_logs([p], input="Pdrag:V", output="Mling:V")
    q = result.bundle.quantities
    assert q.input.unit == q.output.unit == "V" and q.input.column != q.output.column
    assert "pdrag" in q.input.column.lower() and "mling" in q.output.column.lower()
    run = result.bundle.runs[0]
    np.testing.assert_array_equal(run.data[q.input.column], VOLTS)
    np.testing.assert_array_equal(run.data[q.output.column], MICRONS)


def test_controldesk_rasters_become_tables_and_bad_captures_are_named(tmp_path):
    slow = T[::10]
    p = write_controldesk(tmp_path / "two.mat", "cap", [T, slow], [
        ("Vout", "Model Root/Amp", VOLTS, "V", 1), ("Temp", "Model Root/Th", np.full(slow.size, 21.0), "degC", 2)])
    fast, slow_t = read_tables(p, "controldesk")
    assert fast.name == "cap-x1" and slow_t.name == "cap-x2" and slow_t.n_samples == slow.size
    assert "raster X(2)" in slow_t.source
    cut = write_controldesk(tmp_path / "cut.mat", "cut", [T], [("Vout", "Model Root/Amp", VOLTS[:-5], "V", 1)])
    with pytest.raises(bmr.BundleError, match=r"cut.mat: cut: channel 'Vout' has 295 samples but its time axis X\(1\) "
                                           r"has 300 \(truncated capture\?\)"):
        read_tables(cut)
    dup = write_controldesk(tmp_path / "dup.mat", "dup", [T], [
        ("Out1", "Model Root/A", VOLTS, "V", 1), ("Out1", "Model Root/B", MICRONS, "um", 1)])
    [t] = read_tables(dup)
    with pytest.raises(bmr.BmrError, match=r"column 'out1' is ambiguous"):
        t.column("out1")
    np.testing.assert_array_equal(t.column("Model Root/B/Out1")[1], MICRONS)
    damaged = tmp_path / "damaged.mat"
    damaged.write_bytes(V73_HEADER.ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02IM" + b"\x89HDF\r\n\x1a\n" + b"\x00" * 600)
    with pytest.raises(bmr.BmrError, match=r"damaged.mat: cannot be read as a MATLAB v7.3 \(HDF5\) file"):
        read_tables(damaged)


def test_analyzer_rows_that_only_look_like_numbers_are_named(tmp_path):
    # Found by fuzzing the import readers: a row starting with a decimal comma, and rows that read as numbers one
    # by one but not as one table, raised pandas' errors.
    (tmp_path / "comma.txt").write_bytes(b"Time\tVoltage\tDisplacement\ns\tmV\tnm\ncacement\ns\tmV\tnm\nclock\tamp\t"
                                         b"sensor\n,10\t0\t0\n0 0.0 0.0\n 1e-3 5 0me\tVoltage\tDisp\n")
    with pytest.raises(bmr.BundleError, match=r"comma.txt, line \d+: "):
        read_tables(tmp_path / "comma.txt")
    (tmp_path / "mixed.txt").write_bytes(b"e\ts%nsor\n0\t0\xaa\t0\n0.001\xf7\xce\xd1\xc5\t0.3\n0.002:3\t0.61\np\tmV\tnm\n"
                                         b"4\t,3\t0.61\n")
    with pytest.raises(bmr.BundleError, match=r"mixed.txt, lines 6-6: not a table of numbers"):
        read_tables(tmp_path / "mixed.txt")


def test_a_v73_capture_reads_as_its_v7_twin(tmp_path):
    # save -v7.3 stores the capture in HDF5 (struct arrays as references): the same tables as save -v7.
    channels = [("Model Root/Amp/Vout", "Model Root/Amp", VOLTS, "V", 1),
                ("x_um", "Model Root/Sensor", MICRONS, "um", 1)]
    [old] = read_tables(write_controldesk(tmp_path / "v7.mat", "forc_01", [T], channels))
    [new] = read_tables(write_controldesk(tmp_path / "v73.mat", "forc_01", [T], channels, v73=True))
    assert list(new.columns) == list(old.columns) and new.units == old.units and new.time_column == old.time_column
    for k in old.columns:
        np.testing.assert_array_equal(new.columns[k], old.columns[k])
    assert new.meta["RTProgram"] == "piezo_rig.sdf"
    # Plain variables and a matrix of loops, as a script saves them.
    write_mat_v73(tmp_path / "plain.mat", {"H": np.column_stack([VOLTS, 2 * VOLTS]), "B": MICRONS, "t": T,
                                           "note": "two loops"})
    [plain] = read_tables(tmp_path / "plain.mat")
    assert sorted(plain.columns) == ["B", "H[1]", "H[2]", "t"]
    np.testing.assert_array_equal(plain.columns["H[2]"], 2 * VOLTS)


def test_plain_mat_is_not_a_capture(tmp_path):
    from scipy.io import savemat

    savemat(tmp_path / "plain.mat", {"u": VOLTS, "y": MICRONS, "rig": {"t": T}})
    [t] = read_tables(tmp_path / "plain.mat")  # detected: plain variables
    assert set(t.columns) == {"u", "y", "rig.t"}
    with pytest.raises(bmr.BmrError, match=r"plain.mat: not a dSPACE ControlDesk capture: no variable is a struct "
                                           r"with X \(time\) and Y \(channels\) \(variables: u, y, rig\)"):
        read_tables(tmp_path / "plain.mat", "controldesk")


# ------------------------------------------------------------------------------------------------ analyzer
def _loop(k: int) -> np.ndarray:
    t = np.arange(200) * 1e-4
    v = 10.0 * np.sin(2 * np.pi * 50 * t + k)
    return np.column_stack([t, v, -v, 1e-6 * np.cos(2 * np.pi * 50 * t), 20.0 * np.tanh(v / 3.0)])


@pytest.mark.parametrize("brackets", [False, True])
def test_analyzer_export_with_several_tables(tmp_path, brackets):
    header = ["Time s", "Vplus V", "Vminus V", "I1 A", "P1 uC_per_cm2"]
    p = write_aixacct(tmp_path / "forc.dat", [({"Hysteresis Amplitude [V]": "10", "Waveform": "triangle"},
                                               header, _loop(k)) for k in range(3)], bracket_units=brackets)
    tables = read_tables(p)
    assert [t.name for t in tables] == ["forc-1", "forc-2", "forc-3"]
    t = tables[1]
    assert list(t.columns) == ["Time", "Vplus", "Vminus", "I1", "P1"]
    assert t.units["P1"] in ("uC_per_cm2", "uC/cm2") and t.units["Time"] == "s"
    np.testing.assert_allclose(t.columns["P1"], _loop(1)[:, 4], rtol=1e-6)
    assert t.meta["Waveform"] == "triangle" and t.meta["SampleName"] == "C12" and t.meta["table"] == "Table 2"
    assert "table 2, Table 2, header at line" in t.source


def test_analyzer_truncated_headerless_and_wrong_files(tmp_path):
    header = ["Time s", "Vplus V", "P1 uC_per_cm2"]
    p = write_aixacct(tmp_path / "cut.dat", [({}, header, _loop(0)[:, [0, 1, 4]])])
    text = p.read_text(encoding="cp1252").rstrip("\n")
    p.write_text(text[: text.rfind("\t")] + "\n", encoding="cp1252")  # the last line loses its last value
    with pytest.raises(bmr.BundleError, match=r"cut.dat, line \d+: 2 values under a header of 3 \(Time s, Vplus V, "
                                           r"P1 uC_per_cm2\) \(truncated file\?\)"):
        read_tables(p)
    (tmp_path / "comma.dat").write_text("Time s\tVplus V\n0,0\t-1,5E+00\n1,0E-03\t2,25\n")
    [c] = read_tables(tmp_path / "comma.dat")
    np.testing.assert_array_equal(c.columns["Vplus"], [-1.5, 2.25])
    (tmp_path / "word.dat").write_text("Time s\tVplus V\n0\t1.0\n1e-3\tover\n2e-3\t3.0\n")
    with pytest.raises(bmr.BmrError, match=r"word.dat, line 3: not a row of numbers: '1e-3\\tover'"):
        read_tables(tmp_path / "word.dat")
    (tmp_path / "bare.txt").write_text("1.0\t2.0\n3.0\t4.0\n")
    with pytest.raises(bmr.BmrError, match=r"bare.txt, line 1: numbers without a header line"):
        read_tables(tmp_path / "bare.txt", "aixacct")
    pd.DataFrame({"a": [1.0, 2.0], "b": [3.0, 4.0]}).to_csv(tmp_path / "comma.csv", index=False)
    with pytest.raises(bmr.BmrError, match=r"comma.csv: no tab-separated table found"):
        read_tables(tmp_path / "comma.csv", "aixacct")
    (tmp_path / "empty.dat").write_text("\n  \n")
    with pytest.raises(bmr.BmrError, match=r"empty.dat: the file is empty"):
        read_tables(tmp_path / "empty.dat")
    (tmp_path / "head.csv").write_text("time,volts\n")
    with pytest.raises(bmr.BundleError, match=r"head.csv: cannot be read as CSV: no rows of numbers under a header "
                                              r"line \(or without one\) in its first 1 line\(s\) \(empty, truncated"):
        read_tables(tmp_path / "head.csv")
    with pytest.raises(bmr.BmrError, match=r"unknown file format 'xlsx'"):
        read_tables(tmp_path / "head.csv", "xlsx")
    with pytest.raises(bmr.BmrError, match=r"does not exist"):
        read_tables(tmp_path / "nothing.dat")


def test_a_row_of_units_under_the_header_states_the_units(tmp_path):
    # Plotting and logging programs write the units in a row of their own (and a comment row under it).
    rows = "\n".join(f"{t:.4f},{v:.4f},{x:.5f}" for t, v, x in zip(T, VOLTS, MICRONS))
    (tmp_path / "units.csv").write_text("Time,Voltage,Displacement\ns,V,um\n" + rows + "\n", encoding="utf-8-sig")
    [t] = read_tables(tmp_path / "units.csv")
    assert t.unit_of("Time") == "s" and t.unit_of("Voltage") == "V" and t.unit_of("Displacement") == "um"
    np.testing.assert_allclose(t.columns["Displacement"], MICRONS, atol=1e-5)
    tabbed = rows.replace(",", "\t")
    (tmp_path / "origin.txt").write_text("Time\tVoltage\tDisplacement\ns\tmV\tnm\nclock\tamp out\tsensor\n"
                                         + tabbed + "\n")
    [o] = read_tables(tmp_path / "origin.txt")
    assert (o.unit_of("Voltage"), o.unit_of("Displacement")) == ("mV", "nm") and o.n_samples == N
    np.testing.assert_allclose(o.columns["Voltage"], VOLTS, atol=1e-4)
    res = bmr.import_logs([tmp_path / "origin.txt"], input="Voltage:V", output="Displacement:um")
    np.testing.assert_allclose(res.bundle.runs[0].input, VOLTS / 1e3, atol=1e-7)
    # Names that are units themselves are still a header when numbers follow them directly.
    (tmp_path / "tv.csv").write_text("t,V\n0,1\n1,2\n")
    [tv] = read_tables(tmp_path / "tv.csv")
    assert list(tv.columns) == ["t", "V"] and tv.n_samples == 2


def test_a_table_without_a_header_has_numbered_columns(tmp_path):
    rows = "\n".join(f"  {t:.4e}   {v:.4e}   {x:.5e}" for t, v, x in zip(T, VOLTS, MICRONS))
    (tmp_path / "scope.dat").write_text("# scope dump\n# ch1 V, ch2 um\n" + rows + "\n")
    [t] = read_tables(tmp_path / "scope.dat")
    assert list(t.columns) == ["1", "2", "3"] and t.unit_of("2") is None and t.n_samples == N
    np.testing.assert_allclose(t.columns["3"], MICRONS, rtol=1e-5)
    res = bmr.import_logs([tmp_path / "scope.dat"], input="2:V", output="3:um", time="1:s")
    np.testing.assert_allclose(res.bundle.runs[0].t, T, atol=1e-7)


def test_spreadsheets_give_one_table_per_sheet(tmp_path):
    # A workbook as a lab saves it: a sheet of notes, a run with a preamble, a row of units, a text column and a
    # note under the numbers, and a run whose header states its units.
    rows = ([["Piezo stage P-753", None, None, None], ["Operator: A. Silva", None, None, None],
             ["Time", "Voltage", "Displacement", "Remark"], ["s", "V", "µm", None]]
            + [[t, v, x, "ok" if k % 50 == 0 else None] for k, (t, v, x) in enumerate(zip(T, VOLTS, MICRONS))]
            + [[None] * 4, ["stopped by hand", None, None, None]])
    with pd.ExcelWriter(tmp_path / "stage.xlsx") as w:
        pd.DataFrame([["bench notes only"], ["no numbers here"]]).to_excel(w, sheet_name="notes", header=False,
                                                                           index=False)
        pd.DataFrame(rows).to_excel(w, sheet_name="run1", header=False, index=False)
        pd.DataFrame({"t [ms]": T * 1e3, "U [V]": VOLTS, "x [nm]": MICRONS * 1e3}).to_excel(
            w, sheet_name="run2", index=False)
    run1, run2 = read_tables(tmp_path / "stage.xlsx")
    assert run1.name == "stage-run1" and list(run1.columns) == ["Time", "Voltage", "Displacement"]
    assert run1.units == {"Time": "s", "Voltage": "V", "Displacement": "µm"} and run1.n_samples == N
    assert run1.meta["Operator"] == "A. Silva" and "sheet 'run1'" in run1.source
    np.testing.assert_allclose(run1.columns["Displacement"], MICRONS, rtol=1e-14)  # 15 digits stored
    assert run2.units == {"t": "ms", "U": "V", "x": "nm"}
    res = bmr.import_logs([tmp_path / "stage.xlsx"], input="U", output="x:um", time="t")
    np.testing.assert_allclose(res.bundle.runs[0].output, MICRONS, rtol=1e-12)
    np.testing.assert_allclose(res.bundle.runs[0].t, T, atol=1e-12)
    pd.DataFrame({"t [s]": T, "U [V]": VOLTS}).to_excel(tmp_path / "one.ods", index=False, engine="odf")
    [one] = read_tables(tmp_path / "one.ods")
    assert one.name == "one" and one.units == {"t": "s", "U": "V"} and one.n_samples == N
    pd.DataFrame([["only words"], ["here"]]).to_excel(tmp_path / "words.xlsx", header=False, index=False)
    with pytest.raises(bmr.BundleError, match=r"words.xlsx: no sheet holds rows of numbers"):
        read_tables(tmp_path / "words.xlsx")
    (tmp_path / "fake.xlsx").write_text("not a zip archive")
    with pytest.raises(bmr.BundleError, match=r"fake.xlsx: cannot be read as a spreadsheet"):
        read_tables(tmp_path / "fake.xlsx")


def test_a_time_column_named_with_its_unit(tmp_path):
    pd.DataFrame({"time_ms": T * 1e3, "u_V": VOLTS, "x_um": MICRONS}).to_csv(tmp_path / "ms.csv", index=False)
    res = bmr.import_logs([tmp_path / "ms.csv"], input="u_V:V", output="x_um:um")
    np.testing.assert_allclose(res.bundle.runs[0].t, T, atol=1e-9)
    assert res.bundle.sample_rate_hz == pytest.approx(1e3)


# ------------------------------------------------------------------------------------------------ SLAC
def test_slac_tables_in_their_layout(tmp_path):
    cur = np.array([0.0, 82.5, 84.15, 85.8, 84.15, 82.5, 80.85, 82.5])
    bl = 0.0317 * cur + 0.034
    dat, plt = write_slac(tmp_path, 4, cur, bl, comment="Minor hysteresis loop 1")
    [d] = read_tables(dat)
    assert d.name == "run4" and d.time_column is None
    assert list(d.columns) == ["MAIN", "sigMAIN", "BL", "sigBL", "TF", "sigTF", "THsp", "sigTHsp"]
    assert d.units == {"MAIN": "A", "sigMAIN": "A", "BL": "T", "sigBL": "T", "TF": "T/A", "sigTF": "T/A",
                       "THsp": "deg", "sigTHsp": "deg"}
    assert d.meta["Comment"] == "Minor hysteresis loop 1" and d.meta["Run Number"] == "4"
    np.testing.assert_allclose(d.columns["BL"], bl, atol=1e-6)
    assert d.column("sigma")[0] == "sigMAIN"
    [p] = read_tables(plt)
    assert p.name == "run4" and p.time_column == "Time" and p.units["Time"] == "s" and p.units["BL"] == "T"
    assert "sigTHsp" in p.columns  # written +/-sigThsp in this file's header
    assert p.meta["metadata_from"] == "strdat.ru4" and p.meta["Comment"] == "Minor hysteresis loop 1"
    np.testing.assert_allclose(p.columns["MAIN"], cur, atol=1e-6)
    # Its place in the magnet's measurement history: the header's date and time (11-11-2021 14:53:27).
    assert d.recorded == p.recorded and d.recorded is not None and d.recorded.history == "SLAC magnet 4194"
    assert d.recorded.order == 1636642407.0
    # Truncated: the last row lost its last columns.
    lines = plt.read_text().splitlines()
    plt.write_text("\n".join(lines[:-1] + [lines[-1][:30]]) + "\n")
    with pytest.raises(bmr.BundleError, match=r"strplt.ru4, line 9: 3 values where the header names 9 "
                                           r"\(truncated file\?\)"):
        read_tables(plt)
    (tmp_path / "other.txt").write_text("Time\tVolts\n0\t1\n")
    with pytest.raises(bmr.BmrError, match=r"other.txt: not a SLAC magnetic-measurement table"):
        read_tables(tmp_path / "other.txt", "slac")


def test_slac_measurements(slac_data):
    sizes = {3: 61, 4: 42, 5: 22, 6: 42, 7: 10, 8: 10}
    for run, n in sizes.items():
        [d] = read_tables(slac_data / f"strdat.ru{run}")
        [p] = read_tables(slac_data / f"strplt.ru{run}")
        assert d.name == p.name == f"run{run}" and d.n_samples == p.n_samples == n
        assert p.units["BL"] == "T" and p.units["MAIN"] == "A" and p.units["Time"] == "s"
        np.testing.assert_allclose(p.columns["BL"], d.columns["BL"], atol=1e-6)
        assert np.all(np.diff(p.columns["Time"]) > 0)
        assert 1e-6 < np.median(p.columns["sigBL"]) < 1e-4  # the field measurement's sigma, ~1e-5 T


# ------------------------------------------------------------------------------------------------ generic
def test_units_in_csv_and_tdms_headers(tmp_path):
    pd.DataFrame({"Time [ms]": T * 1e3, "Drive (V)": VOLTS, "Force (filtered)": MICRONS}).to_csv(
        tmp_path / "log.csv", index=False)
    [t] = read_tables(tmp_path / "log.csv")
    assert t.units == {"Time": "ms", "Drive": "V"} and "Force (filtered)" in t.columns
    assert t.column("Drive (V)")[0] == "Drive"
    from nptdms import ChannelObject, TdmsWriter

    with TdmsWriter(tmp_path / "r.tdms") as w:
        w.write_segment([ChannelObject("Data", "Vout", VOLTS, properties={"unit_string": "V"}),
                         ChannelObject("Data", "x", MICRONS, properties={"unit_string": "um"})])
    [t] = read_tables(tmp_path / "r.tdms")
    assert t.units == {"Data/Vout": "V", "Data/x": "um"} and t.column("x")[0] == "Data/x"


def test_delimited_logs_with_a_preamble_decimal_commas_and_blanks(tmp_path):
    rows = "\n".join(f"{t:.4f};{v:.6f}".replace(".", ",") + ";ok" for t, v in zip(T[:50], VOLTS[:50]))
    (tmp_path / "eu.csv").write_text("# exported by RigLogger 2.1\nOperator: A. Muster\nSample rate: 1000 Hz\n\n"
                                     "Zeit [s];Spannung [V];Status\n" + rows + "\n")
    [t] = read_tables(tmp_path / "eu.csv")
    assert t.units == {"Zeit": "s", "Spannung": "V"} and t.n_samples == 50 and "Status" not in t.columns
    np.testing.assert_allclose(t.columns["Spannung"], VOLTS[:50], atol=1e-6)
    assert t.meta["Operator"] == "A. Muster" and t.meta["Sample rate"] == "1000 Hz"
    body = "\n".join(f"  {a:.4f}   {b:.5f}" for a, b in zip(T[:20], MICRONS[:20]))
    (tmp_path / "blank.txt").write_text("t x_um\n" + body + "\n")
    [w] = read_tables(tmp_path / "blank.txt", "csv")
    np.testing.assert_allclose(w.columns["x_um"], MICRONS[:20], atol=1e-5)


# ------------------------------------------------------------------------------------ magnetometers (FORCs)
def _forcs(count: int = 6) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[float]]:
    """First-order reversal curves of a Preisach plant on -1..1 (in the file's field unit), each from positive
    saturation down to its reversal field and up to 0.8; and the moment at the calibration field 1 before each,
    drifting by 0.5 % of it from curve to curve."""
    curves, cal = [], []
    for k, hr in enumerate(np.linspace(-0.9, 0.6, count)):
        plant = PreisachPlant(60)
        plant.run(np.array([-1.0, 1.0, hr]))
        h = np.linspace(hr, 0.8, 9 + k)
        curves.append((h, 1e-3 * (plant.run(h) + 2.0)))
        cal.append(1e-3 * 3.0 * (1.0 + 0.005 * k))
    return curves, cal


@pytest.mark.parametrize("system,field_unit,moment_unit", [("cgs", "Oe", "emu"), ("Hybrid SI", "T", "A·m²"),
                                                           ("SI", "A/m", "A·m²")])
@pytest.mark.parametrize("column_header", [False, True])
def test_micromag_forc_export_one_run_per_curve_with_its_calibration_point(tmp_path, system, field_unit,
                                                                           moment_unit, column_header):
    curves, cal = _forcs()
    p = write_micromag(tmp_path / "sample_forc", curves, h_cal=1.0, m_cal=cal, system=system,
                       column_header=column_header)
    tables = read_tables(p)
    assert [t.name for t in tables] == [f"sample_forc-forc{k:03d}" for k in range(1, 7)]
    for t, (h, m), mc in zip(tables, curves, cal):
        assert t.unit_of("Field") == field_unit and t.unit_of("Moment") == moment_unit
        # The calibration point leads its curve and is kept as the drift measurement.
        np.testing.assert_allclose(t.columns["Field"], np.concatenate([[1.0], h]), rtol=1e-6)
        np.testing.assert_allclose(t.columns["Moment"], np.concatenate([[mc], m]), rtol=1e-6)
        assert t.meta["calibration_moment"] == pytest.approx(mc, rel=1e-6) and t.meta["calibration_points"] == 1
    # One history: time runs on through the file.
    assert tables[1].columns["time"][0] > tables[0].columns["time"][-1]
    result = bmr.import_logs([p], input="Field", output="Moment", holdout=["sample_forc-forc002"])
    assert len(result.bundle.runs) == 6 and result.bundle.quantities.output.unit == moment_unit
    # The curves are one measurement history in file order, held-out curves included.
    assert result.bundle.histories == [[f"sample_forc-forc{k:03d}" for k in range(1, 7)]]


def test_lakeshore_forc_export_latin1_blank_lines_and_time_stamps(tmp_path):
    curves, cal = _forcs(4)
    p = write_lakeshore(tmp_path / "B-9-FORC.csv", curves, h_cal=1.0, m_cal=cal)
    tables = read_tables(p)  # detected from the content, not the .csv extension
    assert len(tables) == 4 and tables[0].name == "B-9-FORC-forc001"
    t = tables[2]
    assert t.unit_of("Field") == "T" and t.unit_of("Moment") == "A·m²" and t.time_column == "Time Stamp"
    assert t.column("Field (µ0H)")[0] == "Field"  # the header's full name is an alias
    np.testing.assert_allclose(t.columns["Moment"], np.concatenate([[cal[2]], curves[2][1]]))
    assert "GOOD" not in "".join(t.columns)
    result = bmr.import_logs([p], input="Field:mT", output="Moment")
    np.testing.assert_allclose(result.bundle.runs[0].data["field_mt"].to_numpy()[1:], 1e3 * curves[0][0])
    assert result.bundle.histories == [[f"B-9-FORC-forc{k:03d}" for k in range(1, 5)]]


def test_matrix_columns_in_separate_files_become_one_run_per_loop(tmp_path):
    from scipy.io import savemat

    h = np.stack([a * np.sin(np.linspace(0, 2 * np.pi, 50)) for a in (10.0, 30.0, 90.0)], axis=1)
    savemat(tmp_path / "H_steel.mat", {"HmeasT": h})
    savemat(tmp_path / "B_steel.mat", {"BmeasT": np.tanh(h / 40.0)})
    result = bmr.import_logs([tmp_path / "H_steel.mat", tmp_path / "B_steel.mat"], input="HmeasT:A/m",
                             output="BmeasT:T", holdout=["steel-1"])
    runs = result.bundle.runs
    assert [r.name for r in runs] == ["steel-1", "steel-2", "steel-3"] and runs[0].role == "evaluation"
    for k, r in enumerate(runs):
        np.testing.assert_allclose(r.data["field_strength_a_per_m"], h[:, k])
        np.testing.assert_allclose(r.data["field_t"], np.tanh(h[:, k] / 40.0))
    assert any("separate files" in n for n in result.notes)


def test_an_idle_hold_and_a_final_command_jump_are_left_out_and_named(tmp_path):
    # A capture as a piezo rig writes it: 1 s held at the negative drive limit before the excitation, and the
    # drive set back to 0 V... here from 80 V to 0 V on the capture's last sample while the stack lags.
    from lab_files import Piezo, ramp

    hold = np.zeros(1000)
    drive = ramp([0.0, 100.0, 20.0, 80.0], 0.2)
    volts = np.concatenate([hold, drive, [0.0]])
    t = np.arange(volts.size) * 1e-3
    microns = Piezo(noise_um=0.002).run(volts)
    p = write_controldesk(tmp_path / "track_07.mat", "track_07", [t], [
        ('"Model Root"/"Pdrag"/"In1"', "", volts, "V", 1), ('"Model Root"/"Mling"/"Out1"', "", microns, "um", 1)])
    result = bmr.import_logs([p], input="Pdrag:V", output="Mling:um")
    [run] = result.bundle.runs
    [info] = result.runs
    # (the drive's first sample is the hold's last: kept, it is the state the run starts from)
    assert info.edges.hold == 1000 and info.edges.jump == 1 and info.samples == drive.size
    np.testing.assert_array_equal(run.input, drive)
    assert run.meta["idle_hold_samples"] == 1000 and run.meta["end_jump_samples"] == 1
    assert info.to_dict()["idle_hold_samples"] == 1000
    text = result.summary()
    assert "idle hold at the start, 1000 samples (1 s at 0 V) left out" in text
    assert "command jump at the end, the last 1 sample(s) left out" in text
    kept = bmr.import_logs([p], input="Pdrag:V", output="Mling:um", keep_edges=True)
    assert kept.bundle.runs[0].input.size == volts.size and not kept.runs[0].edges.any
    # A run without such edges (a ramp from its first sample, a FORC's calibration point then its curve) is
    # imported whole.
    plain = write_controldesk(tmp_path / "plain.mat", "plain", [t[:drive.size]], [
        ("In1", "", drive, "V", 1), ("Out1", "", microns[:drive.size], "um", 1)])
    assert not bmr.import_logs([plain], input="In1:V", output="Out1:um").runs[0].edges.any
