"""``python -m arfem.scenarios.geometry.gmsh_models``: a command with ``--help`` that writes only
to the path it is given.

Properties verified: ``--help`` exits 0 and names the argument and the options; no
argument, a bad size or an existing file is one ``arfem: error:`` line, exit 2, nothing
written (not in the working directory, not into the installed package's
``scenarios/data/spindle_unit.msh``); given a path (and Gmsh), the mesh appears there, with
the unit's groups, and nowhere else.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import arfem.scenarios
from arfem.scenarios.geometry.gmsh_models import main

SHIPPED = Path(arfem.scenarios.__file__).parent / "data" / "spindle_unit.msh"


def _cli(args, cwd):
    return subprocess.run([sys.executable, "-m", "arfem.scenarios.geometry.gmsh_models", *args],
                          cwd=cwd, capture_output=True, text=True, timeout=120)


def test_help_is_a_usage_not_a_traceback(tmp_path):
    r = _cli(["--help"], tmp_path)
    assert r.returncode == 0, r.stderr
    assert "OUT.msh" in r.stdout and "--size" in r.stdout and "--force" in r.stdout
    assert "Traceback" not in r.stderr and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args, says", [
    ([], "the following arguments are required: OUT.msh"),
    (["m.msh", "--size", "0"], "--size: must be between 0.5 and 200 mm"),
    (["m.msh", "--size", "10", "--size-min", "20"], "--size-min: must not exceed --size"),
    (["m.txt"], "m.txt: must end in .msh"),
])
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, args, says):
    """No path, an impossible size or a name that is not .msh: one line, exit 2, the
    working directory and the shipped mesh untouched."""
    before = SHIPPED.stat().st_mtime_ns
    r = _cli(args, tmp_path)
    assert r.returncode == 2
    assert r.stderr.startswith("arfem: error: ") and r.stderr.count("\n") == 1, r.stderr
    assert says in r.stderr
    assert list(tmp_path.iterdir()) == [] and SHIPPED.stat().st_mtime_ns == before


def test_an_existing_file_is_not_replaced_without_force(tmp_path, capsys):
    p = tmp_path / "mine.msh"
    p.write_text("my own mesh", encoding="utf-8")
    assert main([str(p)]) == 2
    assert "mine.msh: exists; pass --force" in capsys.readouterr().err
    assert p.read_text(encoding="utf-8") == "my own mesh"


def test_writes_the_mesh_where_it_is_told_and_nowhere_else(tmp_path, monkeypatch):
    """A coarse unit (--size 60) written to a subfolder's path: that file holds every
    group the shipped scenario names, and the folder holds nothing else (no temporary
    left); the working directory gets nothing."""
    pytest.importorskip("gmsh")
    from arfem.fem.gmsh_io import read_grouped_mesh
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "meshes" / "unit.msh"
    assert main([str(out), "--size", "60", "--size-min", "30"]) == 0
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["meshes", "unit.msh"]
    gm = read_grouped_mesh(out, unit="mm")
    names = set(gm.volumes) | set(gm.surfaces)
    assert {"shaft", "front_bearing", "rear_bearing", "stator", "housing", "column",
            "front_bearing_contact", "motor_airgap", "housing_outer",
            "column_foot"} <= names
