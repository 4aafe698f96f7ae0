"""Allocation problem, scenario validation and the ``arfem allocate`` command."""
import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from arfem.models.allocation.problem import allocate, evaluate
from arfem.models.allocation.scenario import build_chain
from arfem.scenarios.allocate import load_allocation_scenario
from arfem.scenarios.cli import main

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "pallet_changer.toml"


@pytest.fixture(scope="module")
def chain_settings():
    sc = load_allocation_scenario(SCENARIO)
    chain, _ = build_chain(sc)
    return chain, sc.settings


@pytest.mark.parametrize("formula", ["screw", "paper"])
def test_every_front_member_meets_the_tolerance(chain_settings, formula):
    """Every returned allocation satisfies m_E ≤ ΔE when re-evaluated independently of the
    optimiser (pymoo's feasibility is G ≤ 0 exactly, so no tolerance beyond 1e-12 relative)."""
    chain, st = chain_settings
    res = allocate(chain, replace(st, formula=formula))
    assert res.feasible and len(res.front_X) >= 1
    ev = evaluate(chain, res.front_X, res.settings)
    assert np.all(ev.m_E_mm <= st.delta_E_mm * (1 + 1e-12))
    lo, hi = chain.bounds()
    assert np.all(res.front_X >= lo) and np.all(res.front_X <= hi)


def test_worst_case_constraint_is_honoured(chain_settings):
    """With constraint = worst_case, any feasible member meets the sign-free bound too; the
    bound is never below the composed m_E (triangle inequality)."""
    chain, st = chain_settings
    res = allocate(chain, replace(st, constraint="worst_case", n_gen=60, pop_size=24))
    ev = res.front
    assert np.all(ev.m_E_worst_case_mm >= ev.m_E_mm * (1 - 1e-12))
    if res.feasible:
        assert np.all(ev.m_E_worst_case_mm <= st.delta_E_mm * (1 + 1e-12))


def test_same_seed_same_front(chain_settings):
    """Seeded reproducibility: the same seed gives the identical front, bit for bit;
    another seed gives a different one (so the seed is really used)."""
    chain, st = chain_settings
    a = allocate(chain, st)
    b = allocate(chain, st)
    np.testing.assert_array_equal(a.front_X, b.front_X)
    np.testing.assert_array_equal(a.front.cost, b.front.cost)
    c = allocate(chain, replace(st, seed=st.seed + 1))
    assert c.front_X.shape != a.front_X.shape or not np.array_equal(c.front_X, a.front_X)


def test_spindle_growth_is_fixed_and_uncosted(chain_settings, tmp_path):
    """A spindle unit carries the AR peak growth (21.60 µm at q = 2000 W/m², paper
    coefficients, 30 s; known from models.ar1) as a fixed Δz: no design variable is added
    and its accuracy at the functional point equals that growth (pure translation)."""
    text = SCENARIO.read_text() + '\n[spindle]\nq_W_m2 = 2000.0\nmodel = "ar"\n'
    text = text.replace("delta_E_mm = 0.005", "delta_E_mm = 0.030")
    p = tmp_path / "s.toml"
    p.write_text(text)
    sc = load_allocation_scenario(p)
    chain, info = build_chain(sc)
    base, _ = chain_settings
    assert len(chain.variables) == len(base.variables)
    assert info["dz_mm"] * 1e3 == pytest.approx(21.598, abs=1e-3)
    res = allocate(chain, sc.settings)
    assert res.feasible
    k = chain.names.index("spindle")
    np.testing.assert_allclose(res.front.unit_accuracy_mm[:, k], info["dz_mm"], rtol=1e-12)


BAD = [
    ("tolerance.delta_E_mm", "delta_E_mm = 0.005", "delta_E_mm = -0.005"),
    ("tolerance.delta_E_mm", "delta_E_mm = 0.005", 'delta_E_mm = "small"'),
    ("tolerance.delta_E_mm", "delta_E_mm = 0.005", "delta_E_mm = nan"),
    ("tolerance.colour", "working_radius_mm = 0.0", "working_radius_mm = 0.0\ncolour = 1"),
    ("units[1].translation_mm", "translation_mm = [0.0, 0.005]\nrotation_mrad = [0.0, 0.005]\n\n"
     "[[units]]\nname = \"gear\"", "translation_mm = [0.005, 0.001]\nrotation_mrad = [0.0, 0.005]"
     "\n\n[[units]]\nname = \"gear\""),
    ("units[0].free", '"dgamma"]', '"dtheta"]'),
    ("optimizer.pop_size", "pop_size = 16", "pop_size = 16.5"),
    ("scenario.formula", 'formula = "screw"', 'formula = "exact"'),
    ("units[3].joint_mm", "joint_deg = 180.0", "joint_mm = 180.0"),
]


@pytest.mark.parametrize("key,old,new", BAD, ids=[b[0] + str(i) for i, b in enumerate(BAD)])
def test_bad_scenario_exits_2_with_one_line(tmp_path, capsys, key, old, new):
    """Bad input (negative/non-numeric/NaN value, unknown key, inverted bounds, unknown
    component, wrong type, unknown choice, joint of the wrong kind) ends with exit status 2
    and ONE stderr line naming the file and the key; nothing is written to --out."""
    text = SCENARIO.read_text()
    assert old in text
    p = tmp_path / "bad.toml"
    p.write_text(text.replace(old, new, 1))
    out = tmp_path / "out"
    rc = main(["allocate", str(p), "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1
    assert err.startswith("arfem: error: ") and str(p) in err and key in err
    assert not out.exists()


def test_malformed_toml_exits_2(tmp_path, capsys):
    """A file that is not TOML is refused with one line naming the file (exit status 2)."""
    p = tmp_path / "broken.toml"
    p.write_text("[tolerance\ndelta_E_mm = 0.005\n")
    assert main(["allocate", str(p), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(p) in err


def test_cli_writes_outputs_and_refuses_nonempty_out(tmp_path, capsys):
    """The command writes the four outputs; allocation.json carries the unit accuracies,
    m_E, h_E and the cost, each with its unit in its name, with m_E ≤ ΔE; a second run
    into the same --out without --force is refused (exit 2)."""
    out = tmp_path / "alloc"
    assert main(["allocate", str(SCENARIO), "--out", str(out)]) == 0
    for f in ("pareto.csv", "allocation.json", "pareto.png", "report.md"):
        assert (out / f).stat().st_size > 0
    a = json.loads((out / "allocation.json").read_text())
    assert set(a["units_accuracy_mm"]) == {"piston", "rack", "gear", "carrier"}
    assert a["m_E_mm"] <= a["delta_E_mm"]
    assert np.isfinite(a["h_E_mm_per_rad"]) and a["cost_rel"] > 0
    assert not {"units", "m_E", "h_E", "cost"} & set(a)       # no unit-less duplicates
    header = (out / "pareto.csv").read_text().splitlines()[0].split(",")
    assert "m_E_mm" in header and "carrier_accuracy_mm" in header
    capsys.readouterr()
    assert main(["allocate", str(SCENARIO), "--out", str(out)]) == 2
    assert "--force" in capsys.readouterr().err
