"""Absurd sizes are refused up front, from an estimate of the work and memory, in one
line naming the key and --allow-large; malformed inputs that used to end in a traceback
are one line too. (Time and peak memory of each refusal: benchmarks/bench_limits.py.)
"""
from __future__ import annotations

import copy
from pathlib import Path

import pytest

from arfem.io import read_toml
from arfem.limits import STRICT, Limits
from arfem.params import InputError
from arfem.scenarios.rod import scenario as config
from arfem.scenarios.cli import main
from arfem.scenarios.rod.scenario import (builtin_scenario_path, estimate_cost, load_scenario,
                                    scenario_from_dict)

BASE = read_toml(builtin_scenario_path("paper_fig2"))


def _with(**tables) -> dict:
    d = copy.deepcopy(BASE)
    for table, kv in tables.items():
        node = d
        for part in table.split("."):
            node = node.setdefault(part, {})
        node.update(kv)
    return d


ABSURD = {   # the fuzzing pass's cases that ran for minutes (7.7 GB, 5.6 GB, 8.5 GB...)
    "dtau_1ms": (_with(ar={"dtau_s": 0.001}), "ar.dtau_s"),
    "backward_euler_1us": (_with(fem={"solver": "backward-euler", "dt_s": 1e-6}), "fem.dt_s"),
    "mesh_4096x4096": (_with(**{"fem.mesh": {"nr": 4096, "nz": 4096}}), "fem.mesh"),
    "mesh_3d_200_200_400": (_with(fem={"model": "3d"},
                                  **{"fem.mesh": {"n_core": 200, "n_ring": 200, "nz": 400}}),
                            "fem.mesh"),
    "snapshots_fields_off_elastic_on": (_with(outputs={"fields": False,
                                                       "field_interval_s": 0.5}),
                                        "outputs.field_interval_s"),
    "field_interval_1e-300": (_with(outputs={"field_interval_s": 1e-300}),
                              "outputs.field_interval_s"),
}


@pytest.mark.parametrize("case", sorted(ABSURD))
def test_absurd_scenarios_are_refused_by_the_loader(case):
    """Each is refused by scenario_from_dict (nothing built) naming its key; the size
    ones name --allow-large."""
    data, key = ABSURD[case]
    with pytest.raises(InputError) as ei:
        scenario_from_dict(data, "x.toml")
    msg = str(ei.value)
    assert "\n" not in msg and f"x.toml: {key}" in msg, msg
    if key != "outputs.field_interval_s":           # the snapshot bound is not lifted
        assert "--allow-large" in msg


def test_absurd_scenario_via_cli_is_one_line_and_out_untouched(tmp_path, capsys):
    """Through `arfem run`: exit 2, one line, --out not created."""
    p = tmp_path / "big.toml"
    p.write_text(builtin_scenario_path("paper_fig2").read_text()
                 + "\n[fem.mesh]\nnr = 4096\nnz = 4096\n")
    assert main(["run", str(p), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "fem.mesh" in err and "GiB" in err
    assert not (tmp_path / "o").exists()


def test_allow_large_lifts_the_size_limits():
    """With Limits(large=True) (what --allow-large passes) the same scenario loads; the
    snapshot bound and the per-direction bound stay."""
    big = Limits(large=True)
    sc = scenario_from_dict(ABSURD["mesh_4096x4096"][0], "x.toml", big)
    assert sc.fem.mesh == {"nr": 4096, "nz": 4096}
    with pytest.raises(InputError, match="snapshots"):
        scenario_from_dict(ABSURD["field_interval_1e-300"][0], "x.toml", big)
    with pytest.raises(InputError, match="GiB"):                  # the default is strict
        scenario_from_dict(ABSURD["mesh_4096x4096"][0], "x.toml", STRICT)


def test_the_environment_still_lifts_the_limits_of_a_library_call(monkeypatch):
    """A library call that passes no Limits reads the user's ARFEM_ALLOW_LARGE=1 (as
    docs/safety.md says); an explicit Limits wins over the environment."""
    monkeypatch.setenv("ARFEM_ALLOW_LARGE", "1")
    assert scenario_from_dict(ABSURD["mesh_4096x4096"][0], "x.toml").fem.mesh["nr"] == 4096
    with pytest.raises(InputError, match="GiB"):
        scenario_from_dict(ABSURD["mesh_4096x4096"][0], "x.toml", STRICT)


def test_the_cli_flag_is_passed_as_a_value_not_through_the_environment(tmp_path, monkeypatch):
    """`--allow-large` is accepted by every subcommand and reaches the scenario reader as
    Limits(large=True); os.environ is the same before, during and after the command."""
    import os
    monkeypatch.delenv("ARFEM_ALLOW_LARGE", raising=False)
    monkeypatch.delenv("ARFEM_ALLOW_CSV_OUTSIDE", raising=False)
    from arfem.scenarios.cli import build_parser
    p = build_parser()
    for argv in (["run", "x.toml", "--out", "o", "--allow-large"],
                 ["diagnose", "x.toml", "--out", "o", "--allow-large"],
                 ["allocate", "x.toml", "--out", "o", "--allow-large"],
                 ["sweep", "x.toml", "--out", "o", "--allow-large"]):
        assert p.parse_args(argv).allow_large
    before = dict(os.environ)
    seen = []

    import arfem.io

    def reader(path, limits=None):               # the one read of the scenario
        seen.append((limits, dict(os.environ) == before))
        return arfem.io.TomlFile(Path(path), "", {})
    monkeypatch.setattr(arfem.io, "read_toml_file", reader)
    main(["run", str(tmp_path / "x.toml"), "--out", str(tmp_path / "o"), "--allow-large"])
    main(["run", str(tmp_path / "x.toml"), "--out", str(tmp_path / "o")])
    assert seen == [(Limits(large=True), True), (STRICT, True)]
    assert dict(os.environ) == before


def test_sweep_points_get_the_limits_as_an_argument(tmp_path):
    """run_sweep passes its Limits to every point's evaluation (a worker process or a
    Dask worker sees no flag of the command that started it)."""
    from arfem.scenarios.sweep.runner import run_sweep
    from arfem.scenarios.sweep.spec import load_sweep
    (tmp_path / "s.toml").write_text('[sweep]\nbase = "paper_fig2"\n'
                                     '[sweep.grid]\ndtau_s = [30, 60]\n')
    sweep = load_sweep(tmp_path / "s.toml", limits=Limits(large=True))
    rep = run_sweep(sweep, tmp_path / "o", workers=1, progress=False,
                    point_fn=_record_limits, limits=Limits(large=True))
    assert rep.n_computed == 2 and _SEEN_LIMITS == [Limits(large=True)] * 2


_SEEN_LIMITS: list = []


def _record_limits(data, source, limits=None):
    _SEEN_LIMITS.append(limits)
    return {"metrics": {"h_W_m2K": 1.0, "fem_peak_um": 1.0}, "run_time_s": 0.0}


#: calls and assignments that write the process environment
_ENV_WRITES = {"update", "pop", "setdefault", "clear", "popitem", "__setitem__",
               "__delitem__"}


def environ_writes(source: str) -> list[int]:
    """Lines of ``source`` that write os.environ (item assignment or deletion, a
    mutating method) or call os.putenv / os.unsetenv."""
    import ast

    def is_environ(node):
        return (isinstance(node, ast.Attribute) and node.attr == "environ") or \
            (isinstance(node, ast.Name) and node.id == "environ")
    lines = []
    for node in ast.walk(ast.parse(source)):
        targets = []
        if isinstance(node, (ast.Assign, ast.AugAssign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
        elif isinstance(node, ast.Delete):
            targets = node.targets
        if any(isinstance(t, ast.Subscript) and is_environ(t.value) for t in targets):
            lines.append(node.lineno)
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            f = node.func
            if (f.attr in _ENV_WRITES and is_environ(f.value)) or \
                    (f.attr in ("putenv", "unsetenv") and isinstance(f.value, ast.Name)
                     and f.value.id == "os"):
                lines.append(node.lineno)
    return lines


def test_the_environment_checker_finds_writes():
    """The checker itself: each way of writing os.environ is found; reading is not."""
    for src in ('os.environ["A"] = "1"\n', "os.environ.update(A='1')\n",
                'os.environ.pop("A", None)\n', 'del os.environ["A"]\n',
                'os.putenv("A", "1")\n', 'from os import environ\nenviron["A"] = "1"\n',
                'os.environ.setdefault("A", "1")\n'):
        assert environ_writes(src), src
    assert environ_writes('x = os.environ.get("A")\ny = os.environ["A"]\n') == []


def test_no_module_of_the_package_writes_the_environment():
    """Permissions travel as a Limits value (issue 31): no module of arfem writes
    os.environ, so a flag cannot leak into another command, test or thread."""
    from pathlib import Path
    repo = Path(__file__).resolve().parents[1]
    found = [f"{p.relative_to(repo)}:{line}"
             for folder in ("arfem", "fem", "models", "scenarios")
             for p in sorted((repo / folder).rglob("*.py"))
             for line in environ_writes(p.read_text(encoding="utf-8"))]
    assert found == []


def test_estimate_matches_the_built_models():
    """The unknown counts of the estimate are exact for the meshes arfem builds (the
    memory/work figures are built on them), checked against assembled models."""
    from arfem.scenarios.rod.evaluation import build_model
    for tables in ({"fem.mesh": {"nr": 3, "nz": 10}},
                   {"fem": {"model": "3d", "order": 1},
                    "fem.mesh": {"n_core": 2, "n_ring": 1, "nz": 4}},
                   {"fem": {"model": "3d", "order": 2},
                    "fem.mesh": {"n_core": 3, "n_ring": 2, "nz": 4}}):
        sc = scenario_from_dict(_with(**tables), "x.toml")
        assert estimate_cost(sc)["ndofs"] == build_model(sc).ndofs


def test_shipped_scenarios_are_far_below_the_limits():
    """The paper's scenarios use under 5 % of each limit (the limits refuse typos, not
    studies)."""
    for name in ("paper_fig2", "paper_fig3"):
        c = estimate_cost(load_scenario(name))
        assert c["memory_bytes"] < 0.05 * config.MAX_MEMORY_BYTES
        assert c["work_flop"] < 0.05 * config.MAX_WORK_FLOP
        assert c["n_samples"] < 0.05 * config.MAX_TIME_STEPS


# -- tracebacks that are one line now ---------------------------------------------------

def test_toml_nested_600_deep_is_one_line(tmp_path, capsys):
    p = tmp_path / "deep.toml"
    p.write_text("x = " + "[" * 600 + "]" * 600 + "\n")
    assert main(["run", str(p), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "nested too deeply" in err


def test_toml_integer_over_4300_digits_is_one_line(tmp_path, capsys):
    p = tmp_path / "big.toml"
    p.write_text("[ar]\ndtau_s = " + "9" * 5000 + "\n")
    assert main(["run", str(p), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "malformed TOML" in err and "Traceback" not in err
