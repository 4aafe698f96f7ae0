"""The promised Python API (:mod:`arfem.api`, re-exported by ``import arfem``).

What is verified and why:
* every name in ``arfem.__all__`` resolves, and every function or class among them has a
  docstring with an example (a ``>>>`` line) -- the promise of issue 22: a name that
  loses its docstring or its example fails here, not silently in the docs;
* ``import arfem`` loads no heavy module (numpy, scipy, matplotlib, the FEM): the import
  stays fast because of laziness, checked structurally rather than by a timed test;
* results convert to pandas and JSON, and a DataFrame with a bad column gets one clear
  error naming ``<DataFrame>`` rather than a temporary file.
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
