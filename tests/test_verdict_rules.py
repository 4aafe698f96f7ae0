"""Issue 41: one verdict module for every plant. Its constants are defined once, in
:mod:`arfem.models.diagnosis.verdict`, and both engines call its rules; a second
definition of a verdict constant anywhere in the package (under its own name or a
known former one) fails here, as does an engine that stops calling the shared rules."""
from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from arfem.models.diagnosis import verdict as vd

ROOT = Path(__file__).resolve().parents[1]
#: the verdict constants, and the names they had in the second engine or a writer
VERDICT_CONSTANTS = {"ALPHA", "WHITE_P", "BETTER_CUT", "UNITS_RATIO", "NO_EFFECT",
                     "MIN_INDEPENDENT_SAMPLES", "RESOLUTION_DEFAULTS", "DEFAULT_RESOLUTION",
                     "VERDICTS", "EDGE_TOL"}
HOME = {"EDGE_TOL": "models/diagnosis/speed_intervals.py"}


def _package_files():
    for sub in ("arfem", "fem", "models", "scenarios", "benchmarks", "reports"):
        for p in sorted((ROOT / sub).rglob("*.py")):
            if ".venv" not in p.parts:
                yield p


def _assigned_names(tree):
    """Names bound at any level by an assignment (``X = ...``, ``X: T = ...``)."""
    for node in ast.walk(tree):
        targets = []
        if isinstance(node, ast.Assign):
            targets = node.targets
        elif isinstance(node, ast.AnnAssign) and node.value is not None:
            targets = [node.target]
        for t in targets:
            for n in ast.walk(t):
                if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store):
                    yield n.id, node.lineno


def test_each_verdict_constant_is_defined_once_in_the_package():
    """An AST scan of every module: each verdict constant is bound exactly once, in its
    home (the verdict module), never beside it (issue 41: ALPHA 1e-3 vs 0.01, UNITS_RATIO
    0.05 vs 0.01, two NO_EFFECT tables)."""
    found = {}
    for p in _package_files():
        tree = ast.parse(p.read_text(encoding="utf-8"), str(p))
        for name, line in _assigned_names(tree):
            if name in VERDICT_CONSTANTS:
                found.setdefault(name, []).append(f"{p.relative_to(ROOT)}:{line}")
    for name in VERDICT_CONSTANTS:
        home = HOME.get(name, "models/diagnosis/verdict.py")
        assert len(found.get(name, [])) == 1, (name, found.get(name))
        assert found[name][0].startswith(home + ":"), (name, found[name])


def test_the_scan_would_see_a_second_definition(tmp_path):
    """The scan is not blind: a module defining ALPHA inside a function is found."""
    tree = ast.parse("def f():\n    ALPHA: float = 0.02\n    x, WHITE_P = 1, 2\n")
    assert {n for n, _ in _assigned_names(tree)} == {"ALPHA", "x", "WHITE_P"}


def test_both_engines_call_the_shared_rules():
    """The pipeline, the rod engine (which writes the pipeline's choice for a q_W_m2
    record and selects on speed-only ones), its rules and the mesh writer import the
    rules from the verdict module rather than writing their own."""
    for rel, names in (("models/geodiagnosis/engine.py", {"whiteness_p", "channels_white",
                                                          "better", "outcome",
                                                          "below_resolution", "naming_level"}),
                       ("models/diagnosis/rules.py", {"units_suspect"}),
                       ("models/diagnosis/engine.py", {"naming_level"}),
                       ("models/geodiagnosis/fit.py", {"NO_EFFECT", "reaches_edge"})):
        tree = ast.parse((ROOT / rel).read_text(encoding="utf-8"))
        got = {a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
               and n.module == "arfem.models.diagnosis.verdict" for a in n.names}
        assert names <= got, (rel, names - got)


@pytest.mark.parametrize("named,failed,noise,floor,beaten,word", [
    (True, [], False, False, False, "established"),
    (True, ["interval holds 1"], True, False, False, "explained"),
    (True, ["interval holds 1"], False, False, False, "unconfirmed"),
    (True, ["interval holds 1"], False, False, True, "not_explained"),
    (False, [], True, False, False, "explained"),
    (False, [], False, False, False, "not_explained"),
    (True, [], False, True, False, "explained"),
    (False, [], False, True, False, "explained"),
])
def test_outcome_follows_the_rules_in_order(named, failed, noise, floor, beaten, word):
    """Rules 0-4 of the verdict module, each case isolated."""
    assert vd.outcome(named, failed, noise, floor, beaten) == word


def test_whiteness_uses_the_floor_stride_and_one_answer_under_ten_samples():
    """⌊N/N_eff⌋ keeps at least N_eff rows; under 10 effective samples the answer is NaN
    and NaN is never white."""
    rng = np.random.default_rng(41)
    r = rng.normal(size=997)
    n_eff = vd.st.noise_n_eff(r)
    stride = int(np.floor(r.size / n_eff))
    assert r[::stride].size >= n_eff
    assert vd.whiteness_p(r) == pytest.approx(vd.st.ljung_box_p(r[::stride], 20))
    slow = np.sin(np.linspace(0, np.pi, 400)) * 30 + rng.normal(size=400)
    assert np.isnan(vd.whiteness_p(slow)) and not vd.channels_white([vd.whiteness_p(slow)])


def test_bonferroni_over_channels_and_thermometers():
    """One family-wise level: a p of 0.02 passes among 5 channels (0.05/5 = 0.01) but
    not alone; the correlation bound widens with the number of thermometers."""
    assert vd.channels_white([0.02] * 5) and not vd.channels_white([0.02])
    assert vd.correlation_bound(200, 13) > vd.correlation_bound(200, 1)
    assert vd.naming_level(4) == vd.ALPHA / 4
