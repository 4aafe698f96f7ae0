"""Tests of arfem.scenarios.records.dataset (the loader): the measured-data contract, read exactly, refused clearly."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from arfem.models.diagnosis.dataset import Dataset, hampel_outliers, sampling_gaps
from arfem.scenarios.records.dataset import load_dataset
from arfem.params import InputError

FL = Path(__file__).resolve().parents[1] / "scenarios" / "data" / "fl_thermal"


def write(tmp_path: Path, csv_text: str, toml_text: str | None = None, stem="case",
          bom=False) -> Path:
    if toml_text is None:
        toml_text = f'[dataset]\nname = "{stem}"\ncsv = "{stem}.csv"\n'
    (tmp_path / f"{stem}.csv").write_bytes(("\ufeff" if bom else "").encode() + csv_text.encode())
    p = tmp_path / f"{stem}.toml"
    p.write_text(toml_text, encoding="utf-8")
    return p


def good_csv(n=40, extra=""):
    head = "time_s,growth_um,q_W_m2" + ("," + extra if extra else "")
    rows = [f"{30 * i},{0.1 * i:.1f},{2000 if i else 0}" + (",1" if extra else "")
            for i in range(n)]
    return "\n".join([head] + rows) + "\n"


def refuse(path: Path, *needles: str) -> str:
    """Load must fail with ONE line that contains the file name and every needle."""
    with pytest.raises(InputError) as ei:
        load_dataset(path)
    msg = str(ei.value)
    assert "\n" not in msg, msg
    for n in needles:
        assert n in msg, f"{n!r} not in {msg!r}"
    return msg


# -- the real recording ------------------------------------------------------------

def test_real_fl_thermal_ch1_loads():
    """The real foreign-format file (non-ASCII mapped columns, BOM-free UTF-8, speed input,
    initial unknown) loads completely: exact row and sensor counts, nothing dropped."""
    ds = load_dataset(FL / "fl_thermal_ch1.toml")
    assert isinstance(ds, Dataset)
    assert ds.input_kind == "speed_rpm" and ds.q_W_m2 is None
    assert ds.n_rows == 11115
    assert len(ds.temperatures) == 16 and "T_t5_C" in ds.temperatures
    assert ds.initial_known is False
    assert ds.time_s[0] == 0.0 and ds.time_s[-1] == 166710.0
    assert np.all(np.diff(ds.time_s) == 15.0) and ds.gaps == []
    assert set(np.unique(ds.speed_rpm)) <= set(range(0, 5001))
    assert ds.speed_rpm.max() == 5000
    # the other four displacement channels are carried and noted
    assert any("ch2(um)" in n and "ignored" in n for n in ds.notes)
    assert ds.extra_columns["ch2(um)"][1] == "0.446569"      # carried verbatim
    assert np.all(np.isfinite(ds.growth_um))
    # flagged outliers are a small minority (a real, low-noise record)
    assert ds.outliers.mean() < 0.02


# -- accepted variations ---------------------------------------------------------------

def test_bom_column_order_and_defaults(tmp_path):
    """A UTF-8 BOM and a free column order are accepted; [rod] keys default to the paper's
    values; absent [dataset] keys default to the stem."""
    csv = "q_W_m2,growth_um,time_s\n0,0,0\n2000,0.2,30\n2000,0.4,60\n"
    p = write(tmp_path, csv, toml_text="[rod]\nconvection_W_m2K = 80.0\n", bom=True)
    ds = load_dataset(p)
    assert ds.name == "case" and ds.initial_known
    assert ds.time_s.tolist() == [0.0, 30.0, 60.0]
    assert ds.q_W_m2.tolist() == [0.0, 2000.0, 2000.0]
    assert ds.rod.convection_W_m2K == 80.0 and ds.rod.radius_m == 0.1
    s = ds.schedule()                 # row at t=0 adds no segment
    assert s.durations_s.tolist() == [30.0, 30.0] and s.q_W_m2.tolist() == [2000.0, 2000.0]


def test_few_empty_rows_dropped_and_reported(tmp_path):
    """<= 5 % rows with empty growth/time are dropped and the note names their CSV lines."""
    lines = good_csv(40).splitlines()
    lines[5] = "120,,2000"            # CSV line 6
    lines[20] = ",1.9,2000"           # CSV line 21
    ds = load_dataset(write(tmp_path, "\n".join(lines) + "\n"))
    assert ds.n_rows == 38
    note = next(n for n in ds.notes if n.startswith("dropped"))
    assert "2 of 40" in note and "6" in note and "21" in note


def test_ambient_gap_filled_and_extra_columns_noted(tmp_path):
    """Short ambient gaps are filled by time interpolation and reported; an unknown column
    is carried and noted; a mapped foreign column is read under its contract name."""
    rows = ["t (s),growth_um,q_W_m2,ambient_C,comment,T_frame_C"]
    for i in range(40):
        amb = "" if i == 10 else f"{20 + 0.1 * i:.1f}"
        rows.append(f"{30 * i},{0.1 * i:.1f},2000,{amb},x,21")
    toml = ('[dataset]\nname = "c"\ncsv = "case.csv"\n[columns]\ntime_s = "t (s)"\n'
            '[sensors.T_frame_C]\ndescription = "bed"\n')
    ds = load_dataset(write(tmp_path, "\n".join(rows) + "\n", toml))
    assert ds.ambient_C[10] == pytest.approx(21.0)
    assert any("filled 1 empty ambient_C" in n for n in ds.notes)
    assert any("comment" in n and "ignored" in n for n in ds.notes)
    assert ds.extra_columns["comment"].tolist() == ["x"] * 40
    assert ds.sensors == {"T_frame_C": "bed"} and "T_frame_C" in ds.temperatures


def test_outliers_and_gaps_flagged(tmp_path):
    """A spike of several µm on a noisy ramp is flagged (and only it); a stretch of missing
    rows longer than 3x the median spacing is reported as a gap."""
    rng = np.random.default_rng(1)
    t = np.arange(300) * 30.0
    t = np.delete(t, np.arange(100, 120))              # 10-min gap
    g = 5 * (1 - np.exp(-t / 3600)) + rng.normal(0, 0.1, t.size)
    g[200] += 4.0
    rows = ["time_s,growth_um,q_W_m2"] + [f"{a:g},{b:.3f},1000" for a, b in zip(t, g)]
    ds = load_dataset(write(tmp_path, "\n".join(rows) + "\n"))
    assert np.flatnonzero(ds.outliers).tolist() == [200]
    assert ds.gaps == [(2970.0, 3600.0)]
    assert any("sampling gaps" in n for n in ds.notes)


def test_hampel_and_gap_helpers():
    """The helpers work on plain arrays (a negative spike counts too)."""
    x = np.linspace(0, 1, 100) + np.random.default_rng(2).normal(0, 0.01, 100)
    x[40] -= 0.5
    assert np.flatnonzero(hampel_outliers(x)).tolist() == [40]
    assert sampling_gaps([0, 1, 2, 3, 10]) == [(3.0, 10.0)]


# -- refusals --------------------------------------------------------------------------

def test_missing_toml(tmp_path):
    """A missing TOML is named."""
    refuse(tmp_path / "nope.toml", "nope.toml", "not found")


def test_missing_csv(tmp_path):
    """A TOML whose CSV is absent names the CSV."""
    p = tmp_path / "a.toml"
    p.write_text('[dataset]\ncsv = "absent.csv"\n')
    refuse(p, "absent.csv", "not found")


def test_malformed_toml(tmp_path):
    """Malformed TOML names the file and the TOML parser's line."""
    refuse(write(tmp_path, good_csv(), "[dataset\nname = 1\n"), "case.toml", "malformed TOML",
           "line 1")


@pytest.mark.parametrize("toml,needle", [
    ('[datset]\nname = "x"\n', "datset: unknown key (did you mean 'dataset'?)"),
    ('[dataset]\nname = "x"\nunits = "SI"\n', "dataset.units"),
    ('[rod]\nradius = 0.1\n', "rod.radius: unknown key (did you mean 'radius_m'?)"),
    ('[rod]\nyoungs_modulus_Pa = 2e11\n', "rod.youngs_modulus_Pa"),
    ('[dataset]\ninitial = "warm"\n', "dataset.initial"),
    ('[columns]\ngrowth = "g"\n', "columns.growth"),
    ('[sensors.T_frame_C]\nplace = "bed"\n', "sensors.T_frame_C.place"),
])
def test_unknown_tables_and_keys(tmp_path, toml, needle):
    """Unknown tables/keys (typos) are refused with the key path, never silently ignored."""
    refuse(write(tmp_path, good_csv(), toml), "case.toml", needle)


@pytest.mark.parametrize("toml,needle", [
    ("[rod]\nradius_m = -0.1\n", "radius_m: must be > 0"),
    ("[rod]\nconvection_W_m2K = 0\n", "convection_W_m2K: must be > 0"),
    ("[rod]\nambient_C = -300.0\n", "ambient_C: is below absolute zero"),
    ('[rod]\nlength_m = "0.8"\n', "rod.length_m: must be a number"),
    ("[rod]\ndensity_kg_m3 = nan\n", "density_kg_m3: must be finite"),
])
def test_nonphysical_rod(tmp_path, toml, needle):
    """Non-physical [rod] values are refused with the key."""
    refuse(write(tmp_path, good_csv(), toml), "case.toml", needle)


def test_missing_required_column(tmp_path):
    """A CSV without growth_um names the CSV and the column."""
    refuse(write(tmp_path, "time_s,q_W_m2\n0,0\n30,1\n"), "case.csv", "'growth_um'")


def test_missing_time_column(tmp_path):
    """A CSV without time_s names the CSV and the column."""
    refuse(write(tmp_path, "growth_um,q_W_m2\n0,0\n1,1\n"), "case.csv", "'time_s'")


def test_neither_input(tmp_path):
    """Neither q_W_m2 nor speed_rpm is refused."""
    refuse(write(tmp_path, "time_s,growth_um\n0,0\n30,1\n"), "case.csv", "q_W_m2", "speed_rpm")


def test_non_increasing_time(tmp_path):
    """Repeated time names the CSV line of the offending row (line 4 = 3rd data row)."""
    refuse(write(tmp_path, "time_s,growth_um,q_W_m2\n0,0,0\n30,1,1\n30,2,1\n"),
           "case.csv", "line 4", "'time_s'", "does not increase")


def test_negative_time(tmp_path):
    """Time before the record start is refused."""
    refuse(write(tmp_path, "time_s,growth_um,q_W_m2\n-30,0,0\n30,1,1\n"),
           "case.csv", "line 2", "negative")


def test_text_in_number_column(tmp_path):
    """Text in a number column names line and column, and quotes the text."""
    lines = good_csv().splitlines()
    lines[7] = "210,abc,2000"
    refuse(write(tmp_path, "\n".join(lines) + "\n"), "case.csv", "line 8", "'growth_um'",
           "'abc'")


def test_decimal_comma_is_a_field_count_error(tmp_path):
    """A row with the wrong number of fields (here a decimal comma) names the line."""
    lines = good_csv().splitlines()
    lines[3] = "60,0,2,2000"
    refuse(write(tmp_path, "\n".join(lines) + "\n"), "case.csv", "line 4", "4 fields")


def test_too_many_empty_rows(tmp_path):
    """More than 5 % rows with an empty growth is refused (3 of 40 = 7.5 %)."""
    lines = good_csv(40).splitlines()
    for k in (5, 6, 7):
        lines[k] = f"{30 * (k - 1)},,2000"
    refuse(write(tmp_path, "\n".join(lines) + "\n"), "case.csv", "3 of 40", "5 %", "line 6")


@pytest.mark.parametrize("cell", ["nan", "NaN", "inf", "-Infinity", "1e999"])
def test_nan_inf_refused(tmp_path, cell):
    """NaN/inf written out (not an empty cell) is refused with line and column."""
    lines = good_csv().splitlines()
    lines[9] = f"270,{cell},2000"
    refuse(write(tmp_path, "\n".join(lines) + "\n"), "case.csv", "line 10", "'growth_um'")


def test_negative_q(tmp_path):
    """A negative heat flux is refused with line and column."""
    lines = good_csv().splitlines()
    lines[4] = "90,0.3,-5"
    refuse(write(tmp_path, "\n".join(lines) + "\n"), "case.csv", "line 5", "'q_W_m2'",
           "negative")


def test_negative_speed_mapped(tmp_path):
    """A negative speed in a mapped foreign column names both names."""
    csv = "time_s,growth_um,rpm\n0,0,0\n30,1,-100\n"
    refuse(write(tmp_path, csv, '[columns]\nspeed_rpm = "rpm"\n'), "case.csv", "line 3",
           "'speed_rpm' ('rpm')", "negative")


def test_mapping_to_absent_column(tmp_path):
    """A [columns] mapping onto a column the CSV lacks names the TOML key and the column."""
    refuse(write(tmp_path, good_csv(), '[columns]\ngrowth_um = "ch1(um)"\n'), "case.toml",
           "columns.growth_um", "'ch1(um)'")


def test_empty_cell_in_carried_speed_is_kept(tmp_path):
    """With q_W_m2 the input, speed_rpm is only carried along: an empty cell there is
    not the input's and is not refused."""
    lines = good_csv().splitlines()
    lines = [lines[0] + ",speed_rpm"] + [l + ",1000" for l in lines[1:]]
    lines[4] = lines[4][:-4]
    ds = load_dataset(write(tmp_path, "\n".join(lines) + "\n"))
    assert ds.input_kind == "q_W_m2"


def test_all_empty_ambient_column_is_absent(tmp_path):
    """An ambient_C column with no value at all is treated as absent (and said so), not
    refused as a column with too many gaps."""
    lines = good_csv().splitlines()
    lines = [lines[0] + ",ambient_C"] + [l + "," for l in lines[1:]]
    ds = load_dataset(write(tmp_path, "\n".join(lines) + "\n"))
    assert ds.ambient_C is None
    assert any("ambient_C" in n and "no value" in n for n in ds.notes)


def test_sensor_table_on_an_extra_column(tmp_path):
    """[sensors.X] on a column that is in the CSV but is not a T_<name>_C temperature
    says so truthfully (it used to claim the column was missing)."""
    lines = good_csv(extra="humidity_pct").splitlines()
    toml = ('[dataset]\nname = "case"\ncsv = "case.csv"\n'
            '[sensors.humidity_pct]\ndescription = "hall humidity"\n')
    ds = load_dataset(write(tmp_path, "\n".join(lines) + "\n", toml))
    assert not any("not in the CSV" in n for n in ds.notes)
    assert any("sensors.humidity_pct" in n and "not a temperature" in n for n in ds.notes)


def test_empty_input_cell(tmp_path):
    """An empty q cell on a kept row is refused (the input must be known everywhere)."""
    lines = good_csv().splitlines()
    lines[4] = "90,0.3,"
    refuse(write(tmp_path, "\n".join(lines) + "\n"), "case.csv", "line 5", "'q_W_m2'", "empty")


def test_not_utf8(tmp_path):
    """A Latin-1 file is refused as not UTF-8."""
    p = write(tmp_path, good_csv())
    (tmp_path / "case.csv").write_bytes("time_s,growth_um,q_W_m2,T_\xb0_C\n0,0,0,1\n"
                                        .encode("latin-1"))
    refuse(p, "case.csv", "line 1", "UTF-8")


@pytest.mark.parametrize("cell", ["\uff11\uff12", "\u0660.\u0665", "1,5"])
def test_non_ascii_digits_are_text(tmp_path, cell):
    """Digits other than ASCII 0-9 (fullwidth, Arabic-Indic) are text, not a number --
    Python's float() would take them, the contract's '.'-decimal CSV does not."""
    lines = good_csv().splitlines()
    lines[3] = f'60,"{cell}",2000'
    refuse(write(tmp_path, "\n".join(lines) + "\n"), "case.csv", "line 4", "'growth_um'")


def test_duplicate_header(tmp_path):
    """A column named twice is ambiguous and refused."""
    refuse(write(tmp_path, "time_s,growth_um,growth_um,q_W_m2\n0,0,0,0\n"), "case.csv",
           "line 1", "twice")


@pytest.mark.parametrize("toml_extra, needles", [
    ("[rod]\nradius_m = 100.0\n", ("rod.radius_m", "plausible", "mm?")),
    ("[rod]\nambient_C = 293.15\n", ("rod.ambient_C", "in K?")),
])
def test_implausible_rod_values(tmp_path, toml_extra, needles):
    """[rod] values in a wrong unit are refused like the scenario keys of `arfem run`
    (one table of plausible ranges, models.params.PLAUSIBLE_RANGES)."""
    toml = '[dataset]\nname = "case"\ncsv = "case.csv"\n' + toml_extra
    refuse(write(tmp_path, good_csv(), toml), "case.toml", *needles)


def test_implausible_columns(tmp_path):
    """A q_W_m2 column a million times too large is refused at its largest row; an
    ambient_C column in kelvin is refused by its median."""
    lines = good_csv().splitlines()
    lines[7] = "180,0.6,2e12"
    refuse(write(tmp_path, "\n".join(lines) + "\n"), "line 8", "'q_W_m2'", "plausible")
    lines = good_csv().splitlines()
    lines = [lines[0] + ",ambient_C"] + [l + ",293.4" for l in lines[1:]]
    refuse(write(tmp_path, "\n".join(lines) + "\n"), "'ambient_C'", "median", "in K?")


# -- safety: sizes, binary files, confinement, line numbers, ranges (issue 17) ---------

def test_growth_um_has_a_plausible_range(tmp_path):
    """growth_um = 1e300 used to end with RMSE inf and gain nan at exit 0: now refused at
    its row, naming the unit expected (growth in µm; 5 mm is a value in nm)."""
    lines = good_csv().splitlines()
    lines[5] = "120,1e300,2000"
    refuse(write(tmp_path, "\n".join(lines) + "\n"), "line 6", "'growth_um'", "plausible",
           "µm")


def test_unterminated_quote_is_reported_where_it_opens(tmp_path):
    """A quote opened on line 12 and never closed makes the csv module read to the end
    of the file; the error names line 12, not the last line."""
    lines = good_csv(n=300).splitlines()
    lines[11] = '330,"1.1,2000'
    msg = refuse(write(tmp_path, "\n".join(lines) + "\n"), "line 12", "quote")
    assert "line 301" in msg         # where the record ran to, said after line 12


def test_nul_bytes_are_refused_before_reading_the_file_whole(tmp_path):
    """A binary file (NUL bytes) is refused from its first 64 KiB, whatever its size."""
    p = write(tmp_path, "")
    (tmp_path / "case.csv").write_bytes(b"\0" * (1 << 20))
    refuse(p, "case.csv", "NUL byte", "byte 0")


def test_too_large_csv_is_refused_by_its_size(tmp_path, monkeypatch):
    """Beyond MAX_CSV_BYTES (here lowered to 1 KiB) the file is refused from its size
    alone, naming --allow-large; with it the same file loads."""
    import arfem.scenarios.records.dataset as dsmod
    monkeypatch.setattr(dsmod, "MAX_CSV_BYTES", 1024)
    p = write(tmp_path, good_csv(n=200))
    refuse(p, "case.csv", "MiB", "--allow-large")
    monkeypatch.setenv("ARFEM_ALLOW_LARGE", "1")
    assert load_dataset(p).time_s.size == 200


def test_too_many_rows_are_refused_before_parsing(tmp_path, monkeypatch):
    """More rows than MAX_ROWS (here lowered to 100) are refused by a line count before
    any cell is parsed; --allow-large lifts it."""
    import arfem.scenarios.records.dataset as dsmod
    monkeypatch.setattr(dsmod, "MAX_ROWS", 100)
    p = write(tmp_path, good_csv(n=200))
    refuse(p, "case.csv", "200 rows", "at most 100", "--allow-large")
    monkeypatch.setenv("ARFEM_ALLOW_LARGE", "1")
    assert load_dataset(p).time_s.size == 200


def test_csv_outside_the_dataset_folder_is_refused_and_never_echoed(tmp_path, monkeypatch):
    """dataset.csv = "../secret/passwords.csv" is refused (paths are confined to the
    TOML's folder); allowed by --allow-csv-outside, a bad cell there is located but
    its content ('hunter2') is never printed."""
    secret = tmp_path / "secret"
    secret.mkdir()
    (secret / "passwords.csv").write_text("time_s,growth_um,q_W_m2\n0,hunter2,0\n")
    d = tmp_path / "case"
    d.mkdir()
    p = d / "case.toml"
    p.write_text('[dataset]\ncsv = "../secret/passwords.csv"\n')
    msg = refuse(p, "dataset.csv", "outside the dataset's folder", "--allow-csv-outside")
    assert "hunter2" not in msg
    monkeypatch.setenv("ARFEM_ALLOW_CSV_OUTSIDE", "1")
    msg = refuse(p, "passwords.csv", "line 2", "is not a number")
    assert "hunter2" not in msg
    (d / "inside.csv").write_text("time_s,growth_um,q_W_m2\n0,oops,0\n")
    p.write_text('[dataset]\ncsv = "inside.csv"\n')
    refuse(p, "'oops' is not a number")            # inside: the cell is shown


def test_symlink_out_of_the_folder_is_outside(tmp_path):
    """A symbolic link beside the TOML that points elsewhere counts as outside."""
    (tmp_path / "elsewhere.csv").write_text(good_csv())
    d = tmp_path / "case"
    d.mkdir()
    (d / "case.csv").symlink_to(tmp_path / "elsewhere.csv")
    (d / "case.toml").write_text('[dataset]\ncsv = "case.csv"\n')
    refuse(d / "case.toml", "outside the dataset's folder")
