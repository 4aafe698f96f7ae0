"""Small sweeps and stand-in point functions for tests that need a sweep store quickly
(issue 29: resume, validation, report after a kill). Not a test module."""
from __future__ import annotations

from pathlib import Path

BASE = """[scenario]
name = "coarse"
[cycle]
phases = [
  { duration_h = 4.0,  q_W_m2 = 2000.0 },
  { duration_h = 1.5,  q_W_m2 = 0.0 },
  { duration_h = 4.0,  q_W_m2 = 2000.0 },
  { duration_h = 14.5, q_W_m2 = 0.0 },
]
[ar]
dtau_s = 600.0
[fem]
model = "axisymmetric"
order = 1
[fem.mesh]
nr = 2
nz = 6
"""


def write_small_sweep(d: Path, grid: str = "h_W_m2K = [20, 55, 150]\n") -> Path:
    """``d/base.toml`` and ``d/small.toml`` (a sweep over ``grid``); returns the sweep."""
    (d / "base.toml").write_text(BASE, "utf-8")
    p = d / "small.toml"
    p.write_text(f'[sweep]\nname = "small"\nbase = "base.toml"\n[sweep.grid]\n{grid}', "utf-8")
    return p


def valid_metrics(h: float, peak_um: float = 10.0) -> dict:
    """Metrics a stored point must hold to be trusted on resume (physical ranges and the
    identities between them, ``sweep.store.record_problem``), with h as the marker."""
    return {"dtau_s": 600.0, "h_W_m2K": h, "q_W_m2": 2000.0, "biot": 0.1, "C1": 0.99,
            "C1_fitted": 0.99, "corrected_C1": 0.99, "fem_peak_um": peak_um,
            "ar_peak_um": peak_um + 0.1, "fem_peak_time_h": 4.0, "max_abs_diff_um": 0.2,
            "max_abs_diff_pct_of_peak": 100 * 0.2 / peak_um, "rmse_um": 0.1,
            "corrected_max_abs_diff_um": 0.02,
            "corrected_max_abs_diff_pct_of_peak": 100 * 0.02 / peak_um,
            "corrected_rmse_um": 0.01, "fem_dofs": 100, "n_samples": 50}


def fake_point(data, source, limits=None):
    """Stand-in for ``evaluate_point`` (same signature, ``limits`` the sweep's
    :class:`arfem.limits.Limits`): valid metrics, h as the marker (picklable)."""
    return {"metrics": valid_metrics(data["rod"]["convection_W_m2K"]), "run_time_s": 0.0}


def flaky_point(data, source, limits=None):
    """As :func:`fake_point`, but h = 55 fails."""
    if data["rod"]["convection_W_m2K"] == 55:
        raise RuntimeError("solver blew up")
    return fake_point(data, source)
