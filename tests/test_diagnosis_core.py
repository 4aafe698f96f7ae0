"""Core checks of the diagnosis forward model and CLI error path."""
import numpy as np

from arfem.fem.heat import build_axisymmetric, solve_modal
from arfem.models.diagnosis.forward import RodModel
from arfem.params import Rod, Schedule
from arfem.scenarios.cli import main as cli


def test_reduced_rod_equals_full_modal_fem_with_switching_h_and_ambient():
    """The growth-mode reduction is exact (not an approximation): it must agree with the
    full modal FEM to round-off (1e-9 µm) for jittered sampling, switching h and ambient."""
    rod = Rod()
    rng = np.random.default_rng(1)
    t = np.cumsum(30 + rng.uniform(-5, 5, 2000))
    q = np.where((t % 30000) < 12000, 2500.0, 0.0)
    amb = 2 * np.sin(t / 20000)
    h = np.where(q > 0, 90.0, 55.0)
    g = RodModel(rod).simulate(t, q, amb, h)
    ref = solve_modal(build_axisymmetric(rod, nr=4, nz=24),
                      Schedule(np.diff(np.r_[0, t]), q, 20 + amb, h), output_times_s=t)
    assert np.max(np.abs(ref.growth_um - g)) < 1e-9


def test_bad_case_exits_2_and_leaves_out_untouched(tmp_path, capsys):
    """A broken dataset gives one error line, exit 2, and no --out directory."""
    bad = tmp_path / "bad.toml"
    bad.write_text('[dataset]\nname = "x"\ncsv = "missing.csv"\n')
    rc = cli(["diagnose", str(bad), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("arfem: error:")
    assert not (tmp_path / "out").exists()
