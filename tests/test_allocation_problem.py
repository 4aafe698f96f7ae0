"""Allocation problem (tolerance model), the mechanism, scenario validation and the CLI."""
import json
from pathlib import Path

import numpy as np
import pytest

from arfem.models.allocation import screw, tolerance
from arfem.models.allocation.problem import (allocate, evaluate_design, knee_index,
                                             unit_values, with_settings)
from arfem.models.allocation.scenario import build_chain
from arfem.params import InputError
from arfem.scenarios.allocation.file import load_allocation_scenario
from arfem.scenarios.cli import main

SCEN = Path(__file__).resolve().parents[1] / "scenarios" / "data"
SCENARIO = SCEN / "pallet_changer.toml"
SMALL = {"pop_size": 40, "n_gen": 40}


@pytest.fixture(scope="module")
def chain_settings():
    sc = load_allocation_scenario(SCENARIO)
    chain, _ = build_chain(sc)
    return chain, with_settings(sc.settings, **SMALL)


def test_rack_and_pinion_gain(chain_settings):
    """A rack error Δx along its axis turns the pinion by Δx / r; the pallet point, 500 mm
    from the pinion axis, moves 500/40 = 12.5·Δx, at every angle of the swing (the arm
    length does not change). Piston Δx acts the same way (rack on the piston rod); Δy
    of the rack (towards the pinion) turns nothing. Exact up to round-off."""
    chain, _ = chain_settings
    Jv, _ = chain.sensitivities()
    names = chain.component_names()
    g = np.linalg.norm(Jv, axis=2)
    for comp in ("rack.dx", "piston.dx"):
        np.testing.assert_allclose(g[:, names.index(comp)], 12.5, rtol=1e-12)
    assert np.all(g[:, names.index("rack.dy")] < 1e-12)


def test_maps_match_exact_kinematics_at_every_pose(chain_settings):
    """The map of a gear error to the pallet point equals the exact displacement of the
    4×4 chain with that error, divided by the error, to O(ε) (ε = 1e-7 rad / mm)."""
    sc = load_allocation_scenario(SCENARIO)
    chain, _ = chain_settings
    gear = next(u for u in sc.units if u.name == "gear")
    carrier = next(u for u in sc.units if u.name == "carrier")
    for p, a in enumerate(sc.travel_angles_deg):
        nominal = gear.pose(a) @ carrier.pose() @ sc.tool
        for j in range(6):
            xi = np.zeros(6)
            xi[j] = 1e-7
            act = gear.pose(a) @ screw.error_transform(xi) @ carrier.pose() @ sc.tool
            d = (act[:3, 3] - nominal[:3, 3]) / 1e-7
            np.testing.assert_allclose(chain.maps[p, 2, 3:, j], d, atol=1e-4 * max(1, np.abs(d).max()))


def test_every_front_member_meets_the_worst_case(chain_settings):
    """Every returned design, re-evaluated independently, has worst case <= ΔE at every
    pose, and a Monte Carlo of it never exceeds its worst case (uniform errors live in
    the zonotope)."""
    chain, st = chain_settings
    res = allocate(chain, st)
    assert res.feasible
    ev = evaluate_design(chain, res.front_X, st)
    assert np.all(ev.worst_case_mm <= st.delta_E_mm * (1 + 1e-12))
    lo, hi = chain.bounds()
    assert np.all(res.front_X >= lo) and np.all(res.front_X <= hi)
    t = unit_values(chain, res.front_X[:1])[0] * np.tile([1, 1, 1, 1e-3, 1e-3, 1e-3], 4)
    Jv, _ = chain.sensitivities()
    mc = tolerance.monte_carlo(t, Jv, st.delta_E_mm, 20_000, "uniform", seed=1)
    assert mc["max_mm"] <= ev.worst_case_mm[0] * (1 + 1e-12) and mc["yield"] == 1.0


def test_history_and_same_seed_same_front(chain_settings):
    """Seeded: the same seed gives the identical front, bit for bit; the hypervolume is
    recorded every generation and never falls (NSGA-II is elitist)."""
    chain, st = chain_settings
    a = allocate(chain, st)
    b = allocate(chain, st)
    np.testing.assert_array_equal(a.front_X, b.front_X)
    hv = a.history["hv"]
    assert len(hv) == a.n_generations and np.all(np.diff(hv) >= -1e-12) and hv[-1] > 0


def test_knee_is_the_bend():
    """On a front with one sharp bend the knee is that bend, not an end."""
    F = np.array([[0.0, 10.0], [0.2, 3.0], [0.3, 1.0], [3.0, 0.5], [10.0, 0.0]])
    assert knee_index(F) == 2


def test_work_limit_refuses_before_starting(chain_settings):
    """pop_size × n_gen above the limit is refused at once (no evaluation done)."""
    chain, st = chain_settings
    with pytest.raises(ValueError, match="evaluations"):
        allocate(chain, with_settings(st, pop_size=10_000, n_gen=100_000))


BAD = [
    ("tolerance.delta_E_mm", "delta_E_mm = 0.005", "delta_E_mm = -0.005"),
    ("tolerance.delta_E_mm", "delta_E_mm = 0.005", 'delta_E_mm = "small"'),
    ("tolerance.delta_E_mm", "delta_E_mm = 0.005", "delta_E_mm = nan"),
    ("tolerance.working_radius_m", "working_radius_mm = 0.0", "working_radius_m = 0.0"),
    ("units[1].translation_mm", 'branch = "drive"\noffset_mm = [250.0, 0.0, 0.0]\n'
     "translation_mm = [0.0001, 0.005]", 'branch = "drive"\noffset_mm = [250.0, 0.0, 0.0]\n'
     "translation_mm = [0.005, 0.001]"),
    ("units[0].free", 'branch = "drive"\n', 'branch = "drive"\nfree = ["dtheta"]\n'),
    ("optimizer.pop_size", "pop_size = 200", "pop_size = 16.5"),
    ("scenario.formula", 'formula = "screw"', 'formula = "paper"'),
    ("transmission.driven_unit", 'driven_unit = "gear"', 'driven_unit = "rack"'),
    ("travel.unit", 'unit = "gear"\nangles', 'unit = "piston"\nangles'),
    ("optimizer.pop_size x optimizer.n_gen", "n_gen = 1000", "n_gen = 100000"),
]


@pytest.mark.parametrize("key,old,new", BAD, ids=[b[0] + str(i) for i, b in enumerate(BAD)])
def test_bad_scenario_exits_2_with_one_line(tmp_path, capsys, key, old, new):
    """Bad input (negative/non-numeric/NaN value, misspelt key, inverted bounds, unknown
    component, wrong type, unknown choice, a transmission or travel naming the wrong unit,
    too much work) ends with exit status 2 and ONE stderr line naming the file and the
    key; nothing is written to --out."""
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


def test_misspelt_key_suggests_the_right_one(tmp_path, capsys):
    """The allocation reader uses arfem.strict: a misspelt key gets "did you mean"."""
    p = tmp_path / "typo.toml"
    p.write_text(SCENARIO.read_text().replace("pitch_radius_mm", "pitch_radius_m"))
    assert main(["allocate", str(p), "--out", str(tmp_path / "o")]) == 2
    assert "did you mean 'pitch_radius_mm'" in capsys.readouterr().err


def test_cli_end_to_end_small(tmp_path, capsys):
    """The command writes its outputs; allocation.json has the worst case <= ΔE, RSS <=
    worst case, both yields, a ranking of all 24 components, each key with its unit; a
    second run into the same --out without --force is refused (exit 2)."""
    p = tmp_path / "small.toml"
    p.write_text(SCENARIO.read_text().replace("pop_size = 200", "pop_size = 40")
                 .replace("n_gen = 1000", "n_gen = 40"))
    out = tmp_path / "alloc"
    assert main(["allocate", str(p), "--out", str(out), "--seeds", "1"]) == 0
    for f in ("pareto.csv", "allocation.json", "pareto.png", "report.md", "stackup.png",
              "sensitivity.png", "convergence.png"):
        assert (out / f).stat().st_size > 0
    a = json.loads((out / "allocation.json").read_text())
    assert a["feasible"] and a["worst_case_um"] <= 1e3 * a["delta_E_mm"] * (1 + 1e-9)
    assert a["rss_um"] <= a["worst_case_um"] and 0 <= a["yield_normal_3sigma"] <= 1
    assert len(a["sensitivity_ranking"]) == 24
    capsys.readouterr()
    assert main(["allocate", str(p), "--out", str(out)]) == 2
    assert "--force" in capsys.readouterr().err


def test_bad_seed_count_refused_before_any_work(tmp_path, capsys):
    """--seeds outside 1..100 is one line, exit 2, before any optimisation (0 is not
    taken as "the default")."""
    out = tmp_path / "o"
    assert main(["allocate", str(SCENARIO), "--out", str(out), "--seeds", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--seeds" in err and not out.exists()


def test_idle_tolerances_are_left_at_their_upper_bound(chain_settings):
    """Components that move the pallet point at no pose (piston and rack Δy, Δz and
    rotations: they do not turn the pinion) cost something and buy nothing: every front
    member has them at the upper bound."""
    chain, st = chain_settings
    res = allocate(chain, st)
    _, hi = chain.bounds()
    names = chain.variable_names()
    for k, n in enumerate(names):
        if n.startswith(("piston_", "rack_")) and not n.split("_")[1] == "dx":
            assert np.all(res.front_X[:, k] == hi[k]), n


def test_the_allocation_reader_refuses_as_the_strict_reader_does():
    """Issue 31: one strict reader. The allocation file's type and finiteness checks are
    arfem.strict's, so a wrong value gets the same one line in every file kind (here a
    boolean for a number, a huge integer, a number for a string)."""
    from arfem import strict
    from arfem.models.allocation.scenario import _Reader
    rd = _Reader("a.toml")
    for value, reader, check in ((True, rd.number, strict.number),
                                 (10 ** 400, rd.number, strict.number),
                                 (3, rd.string, strict.string),
                                 ("yes", rd.boolean, strict.boolean)):
        with pytest.raises(InputError) as mine:
            reader({"k": value}, "k", "t.k", *(() if reader != rd.boolean else (False,)))
        with pytest.raises(InputError) as theirs:
            check(value, "a.toml: t.k")
        assert str(mine.value) == str(theirs.value)
    # integers and the elements of a vector too: a float for a count, and a number too
    # large for a float in a vector (before: an OverflowError traceback from isfinite)
    for value, call, where, kw in ((2.5, lambda v: rd.integer({"k": v}, "k", "t.k", 1, 1, 9),
                                    "a.toml: t.k", {"integer": True}),
                                   (10 ** 400, lambda v: rd.vector({"k": [0, v, 0]}, "k", "t.k"),
                                    "a.toml: t.k[1]", {}),
                                   (float("nan"), lambda v: rd.vector({"k": [v, 0, 0]}, "k",
                                                                      "t.k"),
                                    "a.toml: t.k[0]", {})):
        with pytest.raises(InputError) as mine:
            call(value)
        with pytest.raises(InputError) as theirs:
            strict.number(value, where, **kw)
        assert str(mine.value) == str(theirs.value)
