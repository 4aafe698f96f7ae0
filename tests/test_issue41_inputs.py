"""Issue 41 items 3 and 4: each finding on records and ranges, replayed through the
command (``arfem.scenarios.cli.main``, in process, as a user runs it).

What is verified and why (each finding of the issue is one test or one parameter):

* **one record reader** (``scenarios/records/dataset.py``: every contract version): a record's
  TOML, CSV and a v3 record's scenario are each read once per command (counted at
  ``arfem.io._open_input``, where every input is opened); a CSV named by absolute path
  or ``..`` outside the TOML's folder is refused and never opened, nor quoted; two
  ``speed_rpm`` columns are refused; the size and row limits are in force and
  ``--allow-large`` lifts them; pandas' fast reader and the strict line reader give the
  same numbers to the bit on the shipped real record (the fast one must not move a
  number of the rod's reports);
* **one rule for a cell out of range** (``docs/measured-data.md``): the record is
  refused at that cell, by the reader, before any diagnosis or replay -- a thermometer
  at 1e300 (was "established ... cuts the error by 0 %"), a row of ambient -1e300 in a
  replay (was offsets of 1e299 µm); blank ambient cells follow the contract's rule for
  them (up to 5 % filled in time and said, beyond refused): 15 and 36 rows (were an SVD
  traceback and an AttributeError) now diagnose, 100 rows are refused;
* **one table of ranges** (``arfem/ranges.py``) serves the record reader and the live
  loop's ``plausible_ranges``;
* **scenario ranges** on the mesh as on the rod: a specific heat of 1e308 or 1e-320, a
  sensor direction [nan, 1, 0], a bearing power of 1e308 or 1e300 W, an ambient of 1e300
  or -300 °C, a node at 1e308, a ``.msh`` meshio cannot parse (its own ``sys.exit(1)``):
  each exactly one line ``arfem: error: <file>: <key>: ...``, exit 2, no warning before
  it, nothing written;
* mesh ``run`` honours ``--allow-large``.
"""
from __future__ import annotations

import csv
import shutil
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from arfem.scenarios.cli import main
from geometry_meshes import BOX_TOML, box_meshio, write_msh

HERE = Path(__file__).parent
GEO = HERE / "data" / "geodiag"
FL = HERE.parent / "scenarios" / "data" / "fl_thermal"


def cli(capsys, *argv):
    """(exit status, stdout, stderr) of one whole command."""
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def refused(rc, err, *needles) -> str:
    """Exit 2 with exactly one line ``arfem: error: ...`` holding every needle, and
    nothing else on stderr (no warning, no traceback)."""
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1, err
    assert lines[0].startswith("arfem: error: ") and "Traceback" not in err, err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """A mesh run of the coarse spindle unit (P1, 1261 unknowns, ~2 s): its v3 record
    (1441 rows at 60 s), model.json and scenario copy."""
    d = tmp_path_factory.mktemp("i41run")
    shutil.copy(GEO / "spindle_coarse.msh", d)
    text = (GEO / "spindle_coarse.toml").read_text().replace("picture = true", "picture = false")
    (d / "unit.toml").write_text(text)
    assert main(["run", str(d / "unit.toml"), "--out", str(d / "run"), "--no-progress"]) == 0
    return d / "run"


def record_copy(run_dir, dest: Path, edit=None) -> Path:
    """The run's record, scenario and mesh copied into ``dest``; ``edit(rows)`` may
    change the CSV's rows (a list of lists, the header first)."""
    dest.mkdir(parents=True, exist_ok=True)
    for name in ("record.toml", "scenario.toml", "spindle_coarse.msh", "model.json"):
        shutil.copy(run_dir / name, dest / name)
    with open(run_dir / "record.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    if edit is not None:
        edit(rows)
    with open(dest / "record.csv", "w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    return dest / "record.toml"


def set_cells(column: str, rows_to_set, value: str):
    def edit(rows):
        j = rows[0].index(column)
        for i in rows_to_set:
            rows[i][j] = value
    return edit


@pytest.fixture
def opened(monkeypatch):
    """Every input file opened during the test, counted by resolved path."""
    import arfem.io
    seen = Counter()
    real = arfem.io._open_input

    def counting(path):
        seen[str(Path(path).resolve())] += 1
        return real(path)
    monkeypatch.setattr(arfem.io, "_open_input", counting)
    return seen


# -- records -----------------------------------------------------------------------------

def test_blank_ambient_in_15_rows_is_filled_by_the_contract_rule_and_replayed(
        run_dir, tmp_path, capsys):
    """Finding: 15 blank ambient cells gave an SVD traceback. The one reader applies the
    contract's rule for every version: up to 5 % of the ambient filled in time, said in
    the reader's notes; the replay runs (exit 0) on a finite ambient."""
    from arfem.scenarios.records.georecord import read_mesh_record
    rec = record_copy(run_dir, tmp_path / "r", set_cells("ambient_C", range(100, 115), ""))
    mr = read_mesh_record(rec)
    assert np.isfinite(mr.table.columns["ambient_C"]).all()
    assert any("filled 15 empty ambient_C cells" in n for n in mr.table.notes)
    rc, out, err = cli(capsys, "compensate", tmp_path / "r" / "model.json", rec,
                       "--out", tmp_path / "c")
    assert rc == 0 and "Traceback" not in err, err


def test_blank_ambient_in_36_rows_diagnoses_reading_each_input_once(run_dir, tmp_path,
                                                                     capsys, opened):
    """Finding: 36 blank ambient cells gave an AttributeError; and a mesh diagnose read
    the record's TOML 4 times and its CSV twice. Now: exit 0, the filled cells said on
    the terminal, and the record's TOML, its CSV and the scenario each opened once."""
    rec = record_copy(run_dir, tmp_path / "r", set_cells("ambient_C", range(300, 336), ""))
    rc, out, err = cli(capsys, "diagnose", rec, "--out", tmp_path / "d", "--no-progress")
    assert rc == 0 and "Traceback" not in err, err
    assert "filled 36 empty ambient_C cells" in out
    d = tmp_path / "r"
    for name in ("record.toml", "record.csv", "scenario.toml"):
        assert opened[str((d / name).resolve())] == 1, (name, opened)


def test_blank_ambient_beyond_5_percent_is_refused(run_dir, tmp_path, capsys):
    rec = record_copy(run_dir, tmp_path / "r", set_cells("ambient_C", range(1, 101), ""))
    rc, _, err = cli(capsys, "diagnose", rec, "--out", tmp_path / "d", "--no-progress")
    refused(rc, err, "record.csv", "line 2", "ambient_C", "at most 5 %")
    assert not (tmp_path / "d").exists()


def test_thermometer_at_1e300_in_half_the_rows_is_refused_before_diagnosis(
        run_dir, tmp_path, capsys):
    """Finding: "established ... h_scale = 1 [1, 1] ... cuts the error by 0 %"."""
    rec = record_copy(run_dir, tmp_path / "r",
                      set_cells("T_housing_C", range(720, 1442), "1e300"))
    rc, _, err = cli(capsys, "diagnose", rec, "--out", tmp_path / "d", "--no-progress")
    refused(rc, err, "record.csv: line 721, column 'T_housing_C'", "1e+300",
            "plausible range [-10, 150]")
    assert not (tmp_path / "d").exists()


def test_a_row_of_ambient_minus_1e300_refuses_the_replay(run_dir, tmp_path, capsys):
    """Finding: offsets up to 1e299 µm and an RMS of inf (live held the same row as
    out_of_range). The record rule: refused, at that row, by the reader; the live
    loop's range for that input is the same table's."""
    from arfem.models.compensator import plausible_ranges
    from arfem.ranges import reading_range
    from arfem.scenarios.compensation.model_file import read_model
    rec = record_copy(run_dir, tmp_path / "r", set_cells("ambient_C", [500], "-1e300"))
    rc, _, err = cli(capsys, "compensate", tmp_path / "r" / "model.json", rec,
                     "--out", tmp_path / "c")
    refused(rc, err, "line 501", "ambient_C", "-1e+300", "[-10, 50]")
    assert not (tmp_path / "c").exists()
    live = plausible_ranges(read_model(tmp_path / "r" / "model.json"))
    assert live["ambient_C"] == reading_range("ambient_C") == (-10.0, 50.0)
    assert not live["ambient_C"][0] <= -1e300 <= live["ambient_C"][1]


def test_the_rod_record_follows_the_same_rule(tmp_path, capsys):
    """A version-2 record: a row of ambient -1e300 is refused by the same check."""
    from arfem.models.diagnosis.synth import generate
    from arfem.scenarios.records.synth_files import write_case
    toml = write_case(generate("none", 3, duration_h=3.0, interval_s=60, jitter_s=0.0,
                               n_gaps=0, empty_fraction=0.0, n_outliers=0), tmp_path)
    p = toml.with_suffix(".csv")
    lines = p.read_text().splitlines()
    j = lines[0].split(",").index("ambient_C")
    cells = lines[40].split(",")
    cells[j] = "-1e300"
    lines[40] = ",".join(cells)
    p.write_text("\n".join(lines) + "\n")
    rc, _, err = cli(capsys, "diagnose", toml, "--out", tmp_path / "d", "--no-progress")
    refused(rc, err, "line 41", "ambient_C", "[-10, 50]")


@pytest.mark.parametrize("csv_name", ["/etc/passwd", "../outside/secret.csv"])
@pytest.mark.parametrize("command", ["diagnose", "compensate"])
def test_a_csv_outside_the_records_folder_is_refused_and_never_read(
        run_dir, tmp_path, capsys, opened, csv_name, command):
    """Finding: a system file named by absolute path was read and one of its lines
    quoted. Refused from the TOML alone: the file is never opened, nothing of it shown."""
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside" / "secret.csv").write_text("time_s,d_tcp_z_um\n0,hunter2\n")
    rec = record_copy(run_dir, tmp_path / "r")
    rec.write_text(rec.read_text().replace('csv = "record.csv"', f'csv = "{csv_name}"'))
    args = (["diagnose", rec, "--out", tmp_path / "o", "--no-progress"]
            if command == "diagnose" else
            ["compensate", tmp_path / "r" / "model.json", rec, "--out", tmp_path / "o"])
    rc, _, err = cli(capsys, *args)
    refused(rc, err, "dataset.csv", "outside the dataset's folder")
    assert "hunter2" not in err and "root:" not in err
    secret = (tmp_path / "r" / csv_name).resolve()
    assert opened[str(secret)] == 0 and opened[str(Path("/etc/passwd").resolve())] == 0


def test_two_speed_rpm_columns_are_refused(run_dir, tmp_path, capsys):
    """Finding: two speed_rpm columns were accepted, the first (the growth) used as the
    speed."""
    def edit(rows):
        rows[0][rows[0].index("growth_um")] = "speed_rpm"
    rec = record_copy(run_dir, tmp_path / "r", edit)
    for argv in (["diagnose", rec, "--out", tmp_path / "d", "--no-progress"],
                 ["compensate", tmp_path / "r" / "model.json", rec, "--out", tmp_path / "c"]):
        rc, _, err = cli(capsys, *argv)
        refused(rc, err, "record.csv: line 1", "'speed_rpm' appears twice")


def test_a_renamed_column_onto_one_the_csv_has_is_refused(run_dir, tmp_path, capsys):
    """[columns] speed_rpm = "P_motor_W" while the CSV has its own speed_rpm: two
    columns would give one contract name; refused, not one of them silently dropped."""
    rec = record_copy(run_dir, tmp_path / "r")
    rec.write_text(rec.read_text() + '\n[columns]\nspeed_rpm = "P_motor_W"\n')
    rc, _, err = cli(capsys, "diagnose", rec, "--out", tmp_path / "d", "--no-progress")
    refused(rc, err, "columns.speed_rpm", "speed_rpm")


def test_row_and_size_limits_and_allow_large(run_dir, tmp_path, capsys, monkeypatch):
    """A record beyond the row limit (lowered to 1000 here; 100 000 by default, so a
    647k-row record is refused) or the size limit is refused from a line count or the
    file's size, before parsing, naming --allow-large; with it the replay runs."""
    import arfem.scenarios.records.dataset as dsmod
    rec = record_copy(run_dir, tmp_path / "r")
    model = tmp_path / "r" / "model.json"
    monkeypatch.setattr(dsmod, "MAX_ROWS", 1000)
    rc, _, err = cli(capsys, "compensate", model, rec, "--out", tmp_path / "c")
    refused(rc, err, "record.csv", "1,441 rows", "at most 1,000", "--allow-large")
    rc, _, err = cli(capsys, "diagnose", rec, "--out", tmp_path / "d", "--no-progress")
    refused(rc, err, "--allow-large")
    monkeypatch.setattr(dsmod, "MAX_ROWS", 100_000)
    monkeypatch.setattr(dsmod, "MAX_CSV_BYTES", 1024)
    rc, _, err = cli(capsys, "compensate", model, rec, "--out", tmp_path / "c")
    refused(rc, err, "record.csv", "MiB", "--allow-large")
    monkeypatch.setattr(dsmod, "MAX_ROWS", 1000)
    rc, _, err = cli(capsys, "compensate", model, rec, "--out", tmp_path / "c",
                     "--allow-large")
    assert rc == 0, err


def test_a_replay_reads_each_input_once(run_dir, tmp_path, capsys, opened):
    rec = record_copy(run_dir, tmp_path / "r")
    rc, _, err = cli(capsys, "compensate", tmp_path / "r" / "model.json", rec,
                     "--out", tmp_path / "c")
    assert rc == 0, err
    for name in ("record.toml", "record.csv", "scenario.toml", "model.json"):
        assert opened[str((tmp_path / "r" / name).resolve())] <= 1, (name, opened)
    assert opened[str((tmp_path / "r" / "record.csv").resolve())] == 1


@pytest.mark.parametrize("parser", ["numpy", "pandas"])
@pytest.mark.parametrize("newline", ["\n", "\r\n"], ids=["lf", "crlf"])
def test_the_fast_and_the_strict_csv_readers_agree_to_the_bit(monkeypatch, parser, newline):
    """Each C reader taken where the text holds no quote (numpy's for plain numbers up
    to PLAIN_NUMBERS_MAX_ROWS rows, pandas' above it) against the line-by-line strict
    reader on the shipped real record, with Unix and Windows line ends: the same
    header, lines and numbers, bit for bit (else a number of the rod's reports could
    move). A table with a blank cell is not plain: pandas reads it, the blank NaN."""
    import arfem.io as aio
    if parser == "pandas":
        monkeypatch.setattr(aio, "PLAIN_NUMBERS_MAX_ROWS", 0)
    p = FL / "fl_thermal_whole.csv"
    text = aio.read_text_utf8(p, record=False).replace("\n", newline)
    numeric = lambda h: not h.startswith("ch")                      # noqa: E731
    fast = aio._fast_csv(p, text, numeric, True)
    strict = aio._strict_csv(p, text, numeric, True, repr)
    assert fast is not None and fast.header == strict.header
    assert np.array_equal(fast.lines, strict.lines)
    assert sorted(fast.numbers) == sorted(strict.numbers) and len(strict.cells) == 5
    for k in strict.numbers:
        a, b = fast.numbers[k], strict.numbers[k]
        assert np.array_equal(a.view(np.int64), b.view(np.int64)), k
    for k in strict.cells:                       # a column not read as numbers: its text
        assert list(fast.cells[k]) == list(strict.cells[k]), k
    lines = text.split(newline)
    header = [c.strip() for c in lines[0].split(",")]
    assert (aio._plain_numbers(lines, list(range(len(lines) - 1)), header,
                               numeric) is None) == (parser == "pandas")
    lines[5] = "," + lines[5].split(",", 1)[1]                  # a blank first cell
    assert aio._plain_numbers(lines, list(range(len(lines) - 1)), header,
                              numeric) is None


@pytest.mark.parametrize("cell, needle", [("nan", "not a finite number"),
                                           ("1e999", "overflows"), ("x", "not a number"),
                                           ("inf", "not a finite number")])
def test_a_bad_cell_found_by_the_fast_reader_is_named_by_the_strict_one(
        run_dir, tmp_path, capsys, cell, needle):
    rec = record_copy(run_dir, tmp_path / "r", set_cells("d_tcp_z_um", [77], cell))
    rc, _, err = cli(capsys, "compensate", tmp_path / "r" / "model.json", rec,
                     "--out", tmp_path / "c")
    refused(rc, err, "line 78", "d_tcp_z_um", needle)


# -- scenarios ---------------------------------------------------------------------------

def _box(tmp_path, toml_edit=None, mesh_edit=None) -> Path:
    """The box scenario of tests/geometry_meshes.py (a 1 s run), edited."""
    m = box_meshio()
    if mesh_edit is not None:
        mesh_edit(m)
    write_msh(m, tmp_path / "box.msh")
    text = BOX_TOML if toml_edit is None else toml_edit(BOX_TOML)
    (tmp_path / "box.toml").write_text(text)
    return tmp_path / "box.toml"


def _sub(old, new):
    def edit(text):
        assert old in text
        return text.replace(old, new, 1)
    return edit


def _node(m):
    m.points[5, 0] = 1e308


def _unreadable(tmp):
    (tmp / "box.msh").write_text("hello\n")      # meshio: sys.exit(1) on this one


@pytest.mark.parametrize("toml_edit, mesh_edit, needles", [
    (_sub("specific_heat_J_kgK = 460.0", "specific_heat_J_kgK = 1e308"), None,
     ("material[0].specific_heat_J_kgK", "1e+308", "J/(kg·K)")),
    (_sub("specific_heat_J_kgK = 460.0", "specific_heat_J_kgK = 1e-320"), None,
     ("material[0].specific_heat_J_kgK", "J/(kg·K)")),
    (_sub('direction = "x"', "direction = [nan, 1, 0]"), None,
     ("sensor[0].direction", "finite")),
    (_sub("power_W = [50.0, 0.0]", "power_W = [1e308, 0.0]"), None,
     ("heat_source[0].power_W", "1e+308", "W")),
    (_sub("power_W = [50.0, 0.0]", "power_W = 1e300"), None,
     ("heat_source[0].power_W", "1e+300")),
    (_sub("{ duration_h = 1.0 } ]", "{ duration_h = 1.0, ambient_C = 1e300 } ]"), None,
     ("cycle.phases[1].ambient_C", "1e+300", "°C")),
    (_sub("{ duration_h = 1.0 } ]", "{ duration_h = 1.0, ambient_C = -300.0 } ]"), None,
     ("cycle.phases[1].ambient_C", "-300")),
    (_sub('group = "right"\n', 'group = "right"\nambient_C = 1e300\n'), None,
     ("convection[0].ambient_C",)),
    (_sub("h_W_m2K = { a = 10.0, b = 0.01, m = 1.0 }", "h_W_m2K = { a = 10.0, b = 1.0, "
          "m = 1e308 }"), None, ("convection[0].h_W_m2K (at 1000 rpm)",)),
    (None, _node, ("box.msh", "node 5", "1e+308")),
])
def test_a_mesh_scenario_number_out_of_range_is_one_line(tmp_path, capsys, toml_edit,
                                                         mesh_edit, needles):
    toml = _box(tmp_path, toml_edit, mesh_edit)
    rc, out, err = cli(capsys, "run", toml, "--out", tmp_path / "o", "--no-progress")
    refused(rc, err, f"{toml}: ", *needles)
    assert not (tmp_path / "o").exists() and out == ""


def test_a_mesh_meshio_cannot_parse_is_one_line(tmp_path, capsys):
    """Finding: meshio's own sys.exit(1) (exit 1, its messages on both streams)."""
    toml = _box(tmp_path)
    _unreadable(tmp_path)
    rc, out, err = cli(capsys, "run", toml, "--out", tmp_path / "o", "--no-progress")
    refused(rc, err, "geometry.mesh", "cannot be read as a mesh")
    assert out == "" and not (tmp_path / "o").exists()


@pytest.mark.parametrize("edit, needles", [
    (_sub("specific_heat_J_kgK = 460.0", "specific_heat_J_kgK = 1e308"),
     ("rod.specific_heat_J_kgK", "J/(kg·K)")),
    (_sub('q_W_m2 = 0.0,    label = "pause"', 'q_W_m2 = 0.0, ambient_C = 1e300'),
     ("cycle.phases[1].ambient_C", "[-10, 50]")),
    # the key as every other is named (it read "rod: poisson_ratio: ...")
    (_sub("poisson_ratio = 0.3", "poisson_ratio = 0.6"),
     ("s.toml: rod.poisson_ratio: must lie in",)),
])
def test_the_rod_scenario_uses_the_same_ranges(tmp_path, capsys, edit, needles):
    from arfem.scenarios.rod.scenario import builtin_scenario_path
    text = builtin_scenario_path("paper_fig2").read_text()
    (tmp_path / "s.toml").write_text(edit(text))
    rc, _, err = cli(capsys, "run", tmp_path / "s.toml", "--out", tmp_path / "o",
                     "--no-progress")
    refused(rc, err, *needles)


def test_mesh_run_honours_allow_large_and_reads_its_scenario_once(tmp_path, capsys,
                                                                  monkeypatch, opened):
    """Finding: mesh run dropped --allow-large. The sample limit (lowered to 10 here)
    refuses naming the flag; with it the run completes. The scenario file is opened
    once per run (it was read 3 times)."""
    import arfem.scenarios.geometry.scenario as geo
    toml = _box(tmp_path)
    monkeypatch.setattr(geo, "MAX_SAMPLES", 10)
    rc, _, err = cli(capsys, "run", toml, "--out", tmp_path / "o", "--no-progress")
    refused(rc, err, "fem.output_interval_s", "--allow-large")
    opened.clear()
    rc, _, err = cli(capsys, "run", toml, "--out", tmp_path / "o", "--no-progress",
                     "--allow-large")
    assert rc == 0, err
    assert opened[str(toml.resolve())] == 1, opened
