"""The promised Python API (:mod:`arfem.api`, re-exported by ``import arfem``).

What is verified and why:
* every name in ``arfem.__all__`` resolves, and every function or class among them has a
  docstring with an example (a ``>>>`` line) -- the promise of issue 22: a name that
  loses its docstring or its example fails here, not silently in the docs;
* ``import arfem`` loads no heavy module (numpy, scipy, matplotlib, the FEM): the import
  stays fast because of laziness, checked structurally rather than by a timed test;
* results convert to pandas and JSON, and a DataFrame with a bad column gets one clear
  error naming ``<DataFrame>`` rather than a temporary file;
* ``read_record`` maps the shipped record's foreign column names onto the contract's and
  keeps its ``initial``; ``diagnose`` gives the engine the record's ``initial`` whatever
  the input (TOML, Record, DataFrame), refuses a contradicting one and warns when it
  assumed one; samples are validated in memory by the file reader's checks (no temporary
  file), with the same arrays as the file path (issue 30 item 5, issue 31 item 6);
* ``dir(arfem)`` and ``help(arfem)`` are written for users (issue 30 item 9).
"""
import inspect
import json
import subprocess
import sys

import numpy as np
import pytest

import arfem


def test_every_public_name_resolves_and_has_docstring_and_example():
    missing = []
    for name in arfem.__all__:
        obj = getattr(arfem, name)
        if name == "__version__":
            assert isinstance(obj, str)
            continue
        if not (inspect.isfunction(obj) or inspect.isclass(obj)):
            continue
        doc = inspect.getdoc(obj) or ""
        if not doc.strip():
            missing.append(f"{name}: no docstring")
        elif ">>>" not in doc and not (inspect.isclass(obj) and issubclass(obj, Exception)):
            # result classes are exemplified by the function that returns them
            if not any(name in (inspect.getdoc(getattr(arfem, f)) or "")
                       for f in arfem.__all__ if f != name and f != "__version__"
                       and inspect.isfunction(getattr(arfem, f))):
                missing.append(f"{name}: no example")
    assert not missing, missing


def test_dir_lists_the_api():
    assert {"solve_fem", "ar1", "diagnose", "check", "sweep"} <= set(dir(arfem))


def test_unknown_attribute_is_an_attribute_error():
    with pytest.raises(AttributeError):
        arfem.no_such_thing


def test_import_arfem_loads_no_heavy_module():
    code = ("import sys, arfem; heavy = [m for m in ('numpy', 'scipy', 'matplotlib', "
            "'skfem', 'arfem.fem', 'arfem.models', 'arfem.scenarios', 'arfem.api') "
            "if m in sys.modules]; print(heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]", out


def test_results_convert_to_dataframe_and_json():
    r = arfem.ar1(arfem.Rod(), arfem.paper_cycle(2000.0), dtau_s=600.0)
    df = r.to_dataframe()
    assert list(df.columns) == ["time_s", "growth_um"] and len(df) == 145
    doc = json.loads(r.to_json())
    assert doc["C1"] == pytest.approx(np.exp(-arfem.Rod().convection_W_m2K * 2
                                             / (7850 * 460 * 0.1) * 600.0))


def test_dataframe_error_names_the_dataframe_not_a_temp_file():
    import pandas as pd
    df = pd.DataFrame({"time_s": [0.0, 60.0, 120.0], "q_W_m2": [0.0, 1.0, 1.0]})
    with pytest.raises(arfem.InputError) as exc:
        arfem.diagnose(df)
    msg = str(exc.value)
    assert "<DataFrame>" in msg and "arfem-df-" not in msg and "growth_um" in msg


def test_check_limits_are_validated():
    with pytest.raises(arfem.InputError, match="max_abs_pct"):
        arfem.check("paper_fig2", max_abs_pct=-1.0)


# -- read_record and diagnose's inputs (issue 30 item 5, issue 31 item 6) -------------------

REPO = __import__("pathlib").Path(__file__).resolve().parents[1]
CH2 = REPO / "scenarios" / "data" / "fl_thermal" / "fl_thermal_ch2.toml"


def test_read_record_gives_the_contract_names_and_the_tomls_metadata():
    """The shipped record's CSV has foreign names (``ch2(um)``); read_record maps them
    onto the contract's and carries initial = "unknown" from the TOML."""
    from arfem.scenarios.records.dataset import load_dataset
    rec = arfem.read_record(CH2)
    ds = load_dataset(CH2)
    assert rec.initial == "unknown" and rec.name == "fl_thermal_ch2"
    assert list(rec.data.columns[:3]) == ["time_s", "growth_um", "speed_rpm"]
    assert {f"T_t{i}_C" for i in range(1, 17)} <= set(rec.data.columns)
    assert rec.columns["growth_um"] == "ch2(um)" and rec.units["growth_um"] == "µm"
    assert rec.units["T_t3_C"] == "°C" and rec.units["speed_rpm"] == "1/min"
    np.testing.assert_array_equal(rec.data["growth_um"].to_numpy(), ds.growth_um)
    assert rec.csv_path.name == "fl_thermal_whole.csv" and rec.notes == tuple(ds.notes)


@pytest.fixture
def captured(monkeypatch):
    """The engine replaced by a recorder of the Dataset it is given: what diagnose
    hands the engine is the property tested, not the diagnosis (tested elsewhere)."""
    from arfem.models.diagnosis import engine
    from arfem.models.diagnosis.result import Diagnosis, Holdout, frozen_mapping
    seen = []
    doc = {"cause": "none", "warnings": []}
    diag = Diagnosis("d", "rod_fem", "explained", "", (), None, (), (), (),
                     Holdout(0.0, "", 0, 0.0, None, ()), (), (), False, False,
                     frozen_mapping({"time_s": [0.0]}),
                     engine.RodEvidence(frozen_mapping(doc), (), None))

    def fake(ds, *args, **kwargs):
        seen.append(ds)
        return diag
    monkeypatch.setattr(engine, "diagnose", fake)
    return seen


def test_diagnose_honours_the_records_initial_whatever_the_input(captured):
    rec = arfem.read_record(CH2)
    arfem.diagnose(CH2)
    arfem.diagnose(rec)
    arfem.diagnose(rec.data, initial=rec.initial)
    assert [ds.initial_known for ds in captured] == [False, False, False]
    with pytest.raises(arfem.InputError, match="contradicts the record's initial"):
        arfem.diagnose(CH2, initial="equilibrium")
    with pytest.raises(arfem.InputError, match="contradicts"):
        arfem.diagnose(rec, initial="equilibrium")


def test_diagnose_of_samples_says_when_it_assumed_equilibrium(captured):
    df = {"time_s": [0.0, 60.0, 120.0], "growth_um": [0.0, 0.1, 0.2],
          "q_W_m2": [0.0, 1000.0, 1000.0]}
    said = arfem.diagnose(df).summary["warnings"]
    assert captured[-1].initial_known and any("assumed" in w for w in said)
    assert arfem.diagnose(df, initial="unknown").summary["warnings"] == []
    assert not captured[-1].initial_known


def test_diagnose_of_a_dataframe_writes_and_reads_no_file(captured, monkeypatch):
    """Samples are validated in memory: any temporary folder or CSV reading fails."""
    import tempfile

    import arfem.io

    def refuse(*a, **k):
        raise AssertionError("a file was touched")
    for name in ("mkdtemp", "mkstemp", "TemporaryDirectory", "NamedTemporaryFile"):
        monkeypatch.setattr(tempfile, name, refuse)
    monkeypatch.setattr(arfem.io, "_open_input", refuse)     # where every input is opened
    import pandas as pd
    df = pd.DataFrame({"time_s": [0.0, 60.0, 120.0], "growth_um": [0.0, 0.1, 0.2],
                       "speed_rpm": [0.0, 3000.0, 3000.0], "note": ["a", "b", "c"]})
    arfem.diagnose(df, initial="equilibrium")
    ds = captured[-1]
    assert str(ds.source) == "<DataFrame>" and ds.input_kind == "speed_rpm"
    assert list(ds.extra_columns) == ["note"]


def test_in_memory_samples_get_the_file_readers_checks_row_by_row():
    import pandas as pd
    from arfem.scenarios.records.dataset import dataset_from_columns
    bad = pd.DataFrame({"time_s": [0.0, 60.0, 30.0], "growth_um": [0.0, 0.1, 0.2],
                        "q_W_m2": [0.0, 1.0, 1.0]})
    with pytest.raises(arfem.InputError, match=r"<DataFrame>: row 2, column 'time_s'"):
        arfem.diagnose(bad)
    text = bad.assign(time_s=[0.0, 60.0, 90.0], growth_um=[0.0, "x", 0.2])
    with pytest.raises(arfem.InputError, match=r"<DataFrame>: row 1, column 'growth_um'"):
        dataset_from_columns(text)
    neg = bad.assign(time_s=[0.0, 60.0, 90.0], q_W_m2=[0.0, -5.0, 1.0])
    with pytest.raises(arfem.InputError, match="negative"):
        dataset_from_columns(neg)


def test_samples_in_memory_and_the_same_record_from_its_files_agree():
    """One validation: the shipped record through read_record's DataFrame gives the
    engine the same arrays, outlier flags and gaps as the file reader."""
    from arfem.scenarios.records.dataset import dataset_from_columns, load_dataset
    rec = arfem.read_record(CH2)
    mem = dataset_from_columns(rec.data, initial=rec.initial)
    ds = load_dataset(CH2)
    for key in ("time_s", "growth_um", "speed_rpm"):
        np.testing.assert_array_equal(getattr(mem, key), getattr(ds, key))
    np.testing.assert_array_equal(mem.outliers, ds.outliers)
    assert mem.gaps == ds.gaps and set(mem.temperatures) == set(ds.temperatures)
    assert mem.growth_resolution_um == ds.growth_resolution_um


def test_dir_arfem_shows_the_api_and_no_internals():
    names = dir(arfem)
    assert "read_record" in names and "Record" in names
    assert not [n for n in names if n in ("PackageNotFoundError", "annotations", "api")
                or (n.startswith("_") and n != "__version__")]


def test_help_arfem_opens_with_what_it_is():
    first = arfem.__doc__.strip().splitlines()[0]
    assert "spindle" in arfem.__doc__.split("\n\n")[1] and "layer" not in first.lower()
    assert "read_record" in arfem.__doc__ and "tests/test_layering" not in arfem.__doc__


def test_a_source_checkout_finds_its_subpackages_without_an_editable_install():
    """After ``pip install .`` (not editable), python started from the repository's root
    imports the source folder arfem/ first (the README's example runs from there); its
    subpackages live beside it (pyproject's package-dir), so the package's path must
    reach them. Run with -S (no site-packages, so no editable-install finder) to see the
    source tree alone: arfem.models must resolve to the checkout's models/."""
    import subprocess
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    code = "import importlib.util; print(importlib.util.find_spec('arfem.models').origin)"
    env = {"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin"}
    out = subprocess.run([sys.executable, "-S", "-c", code], cwd=root.parent, env=env,
                         capture_output=True, text=True, check=True).stdout.strip()
    assert Path(out) == root / "models" / "__init__.py"
