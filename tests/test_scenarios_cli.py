"""Scenario files and the `arfem run` / `arfem reproduce` commands.

Bad input must end in one line naming the file and the key, exit status 2, no
traceback, and nothing already in --out lost.
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from arfem.scenarios.cli import main
from arfem.scenarios.rod.scenario import load_scenario, builtin_scenario_path
from scenario_texts import small_scenario

ROOT = Path(__file__).resolve().parents[1]
PAPER2 = ROOT / "scenarios" / "data" / "paper_fig2.toml"


def _write(tmp_path: Path, text: str, name="case.toml") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


GOOD = small_scenario()


@pytest.mark.parametrize("text, where, what", [
    (GOOD.replace("dtau_s = 60.0", "dtau_s = 70.0"), "ar.dtau_s", "does not divide"),
    (GOOD.replace("[ar]", "[ar]\ndtua_s = 1"), "ar.dtua_s", "did you mean 'dtau_s'"),
    (GOOD.replace("duration_h = 1.0, q_W_m2 = 0.0", "duration_h = -1.0, q_W_m2 = 0.0"),
     "cycle.phases[1].duration_h", "must be > 0"),
    (GOOD.replace("[cycle]", "[cycle]\ntotal_h = 3.0"), "cycle.total_h", "add up to 2"),
    (GOOD.replace("nr = 2", 'nr = "two"'), "fem.mesh.nr", "must be a number"),
    (GOOD.replace("[scenario]", "[rod]\nradius_m = 100.0\n[scenario]"), "rod.radius_m",
     "plausible range"),
    (GOOD.replace("[scenario]", "[rod]\nexpansion_1_K = 12.0\n[scenario]"), "rod.expansion_1_K",
     "plausible range"),
    (GOOD.replace("[scenario]", "[rod]\nconvection_W_m2K = nan\n[scenario]"),
     "rod.convection_W_m2K", "finite"),
    (GOOD.replace("nz = 8", "nz = 0"), "fem.mesh.nz", "at least 1 element"),
    (GOOD.replace("nz = 8", "nz = 100000000"), "fem.mesh.nz", "at most 4096"),
    (GOOD.replace("nz = 8", "nz = " + "9" * 400), "fem.mesh.nz", "too large for a number"),
    (GOOD.replace("fields = false", "fields = true\nfield_interval_s = 0.01"),
     "outputs.field_interval_s", "at most 5000"),
    (GOOD.replace("q_W_m2 = 2000.0", "q_W_m2 = 0.0"), "cycle.phases", "no phase heats"),
    (GOOD.replace("{ duration_h = 1.0, q_W_m2 = 0.0 }",
                  "{ duration_h = 1.0, q_W_m2 = 0.0, ambient_C = 293.0 }"),
     "cycle.phases[1].ambient_C", "in K?"),
    (GOOD + "\n[extra]\n", "extra", "unknown key"),
    ("this is = not [toml", "", "malformed TOML"),
])
def test_bad_scenario_is_one_line_exit_2(tmp_path, capsys, text, where, what):
    """Every malformed scenario gives exit 2 and one stderr line naming file, key and fault."""
    p = _write(tmp_path, text)
    out = tmp_path / "out"
    rc = main(["run", str(p), "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1, err
    assert str(p) in err and where in err and what in err, err
    assert "Traceback" not in err
    assert not out.exists()


def test_missing_file_exit_2(tmp_path, capsys):
    rc = main(["run", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and "nope.toml: file not found" in err


def test_cli_subprocess_has_no_traceback(tmp_path):
    """The console entry point itself (not only main()) ends bad input with status 2."""
    p = _write(tmp_path, GOOD.replace("dtau_s = 60.0", "dtau_s = 70.0"))
    r = subprocess.run([sys.executable, "-c", "import sys; from scenarios.cli import main; "
                        "sys.exit(main(sys.argv[1:]))", "run", str(p), "--out",
                        str(tmp_path / "o")], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr


def test_run_refuses_nonempty_out_and_keeps_user_files(tmp_path, capsys):
    """A non-empty --out is refused without --force; with --force only arfem's files change."""
    p = _write(tmp_path, GOOD)
    out = tmp_path / "out"
    out.mkdir()
    mine = out / "notes.txt"
    mine.write_text("mine")
    assert main(["run", str(p), "--out", str(out)]) == 2
    assert "--force" in capsys.readouterr().err
    assert sorted(x.name for x in out.iterdir()) == ["notes.txt"]
    assert main(["run", str(p), "--out", str(out), "--force"]) == 0
    assert mine.read_text() == "mine"
    names = {x.name for x in out.iterdir()}
    assert {"timeseries.csv", "summary.json", "figure.png", "summary.md"} <= names
    # no staging debris; the one hidden file is the ownership manifest, which lists
    # arfem's files and not the user's
    assert [n for n in names if n.startswith(".")] == [".arfem-outputs.json"], names
    owned = json.loads((out / ".arfem-outputs.json").read_text())["files"]
    assert "notes.txt" not in owned and {"summary.json", "figure.png"} <= set(owned)


def test_run_outputs_are_consistent(tmp_path):
    """timeseries.csv and summary.json describe the same run: the summary's peak and max
    difference are recomputed from the CSV columns (to the CSV's 10 significant digits)."""
    p = _write(tmp_path, GOOD)
    out = tmp_path / "out"
    assert main(["run", str(p), "--out", str(out)]) == 0
    data = np.genfromtxt(out / "timeseries.csv", delimiter=",", names=True)
    for col in ("time_s", "q_W_m2", "fem_growth_um", "ar_growth_um", "ar_corrected_growth_um"):
        assert col in data.dtype.names
    s = json.loads((out / "summary.json").read_text())
    for key in ("C1", "C2_um", "C1_fitted", "C2_fitted_um", "fem_peak_um", "ar_peak_um",
                "max_abs_diff_um", "max_abs_diff_pct_of_peak", "rmse_um",
                "corrected_max_abs_diff_um", "corrected_max_abs_diff_pct_of_peak"):
        assert key in s, key
    assert s["fem_peak_um"] == pytest.approx(data["fem_growth_um"].max(), rel=1e-8)
    diff = np.abs(data["ar_growth_um"] - data["fem_growth_um"]).max()
    assert s["max_abs_diff_um"] == pytest.approx(diff, rel=1e-6)
    assert np.allclose(np.diff(data["time_s"]), 60.0)


def test_builtin_paper_scenarios_are_the_papers():
    """The shipped scenarios encode the paper's rod, cycle (4/1.5/4/14.5 h) and q levels."""
    for name, q in (("paper_fig2", 2000.0), ("paper_fig3", 3000.0)):
        sc = load_scenario(builtin_scenario_path(name))
        assert sc.schedule.durations_s.tolist() == [14400.0, 5400.0, 14400.0, 52200.0]
        assert sc.schedule.q_W_m2.tolist() == [q, 0.0, q, 0.0]
        assert sc.dtau_s == 30.0 and sc.rod.convection_W_m2K == 55.0
        assert sc.rod.radius_m == 0.1 and sc.rod.length_m == 0.8


def test_reproduce_writes_both_figures_and_refuses_foreign_dir(tmp_path, capsys):
    """reproduce fills its directory; a second run replaces its own output; a foreign
    non-empty directory is refused."""
    out = tmp_path / "paper"
    assert main(["reproduce", "--out", str(out)]) == 0
    for name in ("paper_fig2", "paper_fig3"):
        assert (out / name / "figure.png").stat().st_size > 10_000
        s = json.loads((out / name / "summary.json").read_text())
        assert s["C1"] == pytest.approx(0.9909, abs=5e-5)
        assert (out / name / "temperature_3d.png").stat().st_size > 10_000
        assert (out / name / "fields" / "fields.xdmf3").is_file()
        # the elastic growth at the peak equals the volume measure (reciprocity theorem)
        assert s["reciprocity_rel_diff"] < 1e-6
        assert s["elastic_growth_face_um_at_peak"] == pytest.approx(s["fem_peak_um"], rel=1e-6)
    readme = (out / "README.md").read_text()
    assert "0.1985" in readme and "0.2977" in readme
    assert main(["reproduce", "--out", str(out)]) == 0       # own output: replaced
    (out / "README.md").write_text("my notes")              # ... unless someone edited it
    capsys.readouterr()
    assert main(["reproduce", "--out", str(out)]) == 2
    assert "README.md" in capsys.readouterr().err
    assert (out / "README.md").read_text() == "my notes"
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "x").write_text("keep")
    assert main(["reproduce", "--out", str(foreign)]) == 2
    assert (foreign / "x").read_text() == "keep"


@pytest.mark.parametrize("argv, needle", [
    (["run"], "required"),
    (["bogus"], "invalid choice"),
    (["diagnose", "x.toml", "--out", "o", "--holdout-start", "abc"], "invalid float"),
])
def test_usage_errors_are_one_line(capsys, argv, needle):
    """argparse's own errors follow the house format: one line, status 2."""
    with pytest.raises(SystemExit) as ei:
        main(argv)
    err = capsys.readouterr().err
    assert ei.value.code == 2 and err.count("\n") == 1 and needle in err, err


def test_out_paths_that_cannot_be_directories(tmp_path, capsys):
    """--out under a file, a broken symlink, or with a directory where arfem writes a
    file (even with --force): one line, status 2, before any work, nothing changed."""
    p = _write(tmp_path, GOOD)
    (tmp_path / "afile").write_text("x")
    (tmp_path / "lnk").symlink_to(tmp_path / "nowhere")
    clash = tmp_path / "clash"
    (clash / "summary.json").mkdir(parents=True)
    for out, force, needle in ((tmp_path / "afile" / "o", [], "not a directory"),
                               (tmp_path / "lnk", [], "broken symbolic link"),
                               (clash, ["--force"], "summary.json is a directory")):
        assert main(["run", str(p), "--out", str(out)] + force) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and needle in err, err
    assert sorted(x.name for x in clash.iterdir()) == ["summary.json"]
    assert not [x for x in tmp_path.iterdir() if "staging" in x.name]
