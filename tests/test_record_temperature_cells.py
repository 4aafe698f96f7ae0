"""Every temperature cell of a measured record is a temperature (issue 29).

Found by the whole-command fuzz of issue 29: one cell of -1e308 °C in a part's
temperature column made ``arfem diagnose`` print a hold-out RMSE of inf µm with exit 0,
and a single absurd ambient cell passed the ambient column's median check. Property: a
cell below absolute zero or above 1000 °C in ``T_<name>_C``, or outside the plausible
ambient range in ``ambient_C``, is one :class:`InputError` naming the CSV's line and
column; ordinary readings (and empty cells) still load.
"""
from __future__ import annotations

import pytest

from arfem.params import InputError
from arfem.scenarios.records.dataset import load_dataset


@pytest.fixture
def record(tmp_path):
    from arfem.models.diagnosis.synth import generate
    from arfem.scenarios.records.synth_files import write_case
    case = generate("none", 5, duration_h=3.0, interval_s=60, jitter_s=0.0, n_gaps=0,
                    empty_fraction=0.0, n_outliers=0)
    toml = write_case(case, tmp_path)
    csv = toml.with_suffix(".csv")
    lines = csv.read_text("utf-8").splitlines()
    lines = [lines[0] + ",T_part_C"] + [ln + ",25.0" for ln in lines[1:]]
    csv.write_text("\n".join(lines) + "\n", "utf-8")
    return toml, csv


def _set_cell(csv, row: int, col: str, value: str) -> None:
    lines = csv.read_text("utf-8").splitlines()
    hdr = lines[0].split(",")
    cells = lines[row].split(",")
    cells[hdr.index(col)] = value
    lines[row] = ",".join(cells)
    csv.write_text("\n".join(lines) + "\n", "utf-8")


def test_ordinary_readings_and_an_empty_cell_load(record):
    toml, csv = record
    _set_cell(csv, 7, "T_part_C", "")
    assert "T_part_C" in load_dataset(toml).temperatures


@pytest.mark.parametrize("col,value", [("T_part_C", "-1e308"), ("T_part_C", "-300"),
                                       ("T_part_C", "1e6"), ("ambient_C", "500"),
                                       ("ambient_C", "-1e308")])
def test_an_impossible_temperature_cell_is_one_line_naming_it(record, col, value):
    toml, csv = record
    _set_cell(csv, 9, col, value)
    with pytest.raises(InputError) as e:
        load_dataset(toml)
    msg = str(e.value)
    assert "line 10" in msg and col in msg and "\n" not in msg, msg


@pytest.mark.parametrize("value", [-1e308, 1500.0, float("inf")])
def test_a_record_held_in_memory_is_checked_as_the_file_is(record, value):
    """The same record as a dict of columns (arfem.diagnose(DataFrame)'s path) is refused
    on the same cell: the in-memory reader once repeated the file reader's checks and
    lacked this one (a -1e308 °C cell loaded from a DataFrame, not from the CSV)."""
    import csv as csv_module

    from arfem.scenarios.records.dataset import dataset_from_columns
    _, csv = record
    with open(csv, newline="", encoding="utf-8") as fh:
        rows = list(csv_module.DictReader(fh))
    cols = {k: [float(r[k]) if r[k] else float("nan") for r in rows]
            for k in ("time_s", "growth_um", "q_W_m2", "T_part_C")}
    assert dataset_from_columns(cols, initial="equilibrium").temperatures["T_part_C"].size
    cols["T_part_C"][4] = value
    with pytest.raises(InputError) as e:
        dataset_from_columns(cols, initial="equilibrium")
    assert "T_part_C" in str(e.value) and "\n" not in str(e.value)
