"""The checks of ``arfem check`` ("the AR(1) model tracks the FEM", a gate for a user's
CI) and their JUnit XML and JSON reports; the command (:mod:`arfem.scenarios.commands.check`)
only parses and prints.

Each scenario is run (FEM and AR(1) on its cycle, :func:`arfem.scenarios.rod.evaluation.evaluate`)
and the chosen AR(1) model (the paper's eqs. 12-14, or the radial-mode corrected one) is
held to two criteria, the ones of :func:`arfem.models.checks.check_ar_tracks_fem`:

* ``max_abs_diff_pct_of_peak``: max|AR - FEM| over the cycle, in % of the FEM peak
  growth, must not exceed its limit (default 3 %);
* ``C1_abs_diff``: |C1 fitted to the FEM series (eq. 17) - C1 of the AR (eq. 13)| must not
  exceed its limit (default 5e-4).

Limits come from the command line, else from the scenario's ``[check]`` table, else the
defaults (:data:`arfem.models.checks.MAX_DEV_OF_PEAK`, :data:`~arfem.models.checks.C1_TOL`).

A scenario on a mesh (``[geometry]``, issue 32 item 4) is checked by
:mod:`arfem.scenarios.geometry.check`: the slowest-mode (``--model corrected``, its
default) or the lumped (``--model paper``) AR(1) of the geometry, superposed over the
sources, per displacement sensor, max|AR − FEM| in % of the largest FEM drift (default
limit 15 %); the other AR's error is reported in ``notes``.

Exit status: 0 every criterion of every scenario holds, 1 at least one fails, 2 bad input
(nothing run). A directory argument checks the run scenarios directly in it; sweep,
allocation and measured-data TOML files and subdirectories are listed as skipped, with why.
``--junit`` writes JUnit XML (one test case per scenario and criterion), ``--json`` the
same as data; both atomically.
"""
from __future__ import annotations

import time

from arfem.io import read_toml
from arfem.models.checks import C1_TOL, MAX_DEV_OF_PEAK, check_ar_tracks_fem
from arfem.models.ar1 import ar1_on_schedule, c1_paper, corrected_coefficients
from arfem.params import InputError, Rod
from arfem.scenarios.rod.deterministic import blas_threads
from arfem.scenarios.gate import Criterion, ScenarioResult, Skipped, result_line
from arfem.scenarios.geometry.check import check_geometry_case, geometry_case_from_dict
from arfem.scenarios.rod.scenario import Scenario, check_limit, scenario_from_dict
from arfem.scenarios.shipped import scenario_file

__all__ = ["collect", "check_scenario", "check_case", "run_checks",
           "DEFAULT_MAX_ABS_PCT", "DEFAULT_MAX_C1_DIFF"]

#: Defaults: the limits of this project's own test (tests/test_ar_tracks_fem.py).
DEFAULT_MAX_ABS_PCT = 100.0 * MAX_DEV_OF_PEAK        # [% of the FEM peak]
DEFAULT_MAX_C1_DIFF = C1_TOL                         # [-]

#: Top-level tables that mark a TOML file as another command's input.
_OTHER_KINDS = (("sweep", "a sweep file (run it with arfem sweep)"),
                ("dataset", "a measured-data case (run it with arfem diagnose)"),
                ("units", "a precision-allocation file (run it with arfem allocate)"),
                ("optimizer", "a precision-allocation file (run it with arfem allocate)"))


# -- which files ---------------------------------------------------------------------------

def _kind(data: dict, in_dir: bool) -> str | None:
    """Why a TOML document is not a run scenario, or None if it is one. In a directory,
    a file without the [cycle] every scenario needs (a pyproject.toml, say) is not one."""
    for key, why in _OTHER_KINDS:
        if key in data:
            return why
    if in_dir and "cycle" not in data:
        return "not an arfem scenario (it has no [cycle] table)"
    return None


def collect(paths, limits=None) -> tuple[list[Scenario], list[Skipped]]:
    """Load every scenario named by ``paths`` (files, directories, built-in names).

    A directory contributes its ``*.toml`` files (not its subdirectories); those that are
    another command's input are returned as :class:`Skipped`. A file named explicitly
    must be a run scenario. Every scenario is validated before any is run: the first
    bad one raises :class:`InputError`.
    """
    scenarios, skipped, seen = [], [], set()
    if not paths:
        raise InputError("name at least one scenario file or directory", "SCENARIO_OR_DIR")
    for arg in paths:
        p = scenario_file(arg)
        if p.is_dir():
            entries = sorted(p.iterdir())
            files = [e for e in entries if e.is_file() and e.suffix == ".toml"]
            for e in entries:
                if e.is_dir() and not e.name.startswith("."):
                    skipped.append(Skipped(f"{e}/", "a subdirectory (arfem check does not "
                                                    "descend; name it to check it)"))
            if not files:
                raise InputError("holds no *.toml file", str(p))
            explicit = False
        elif p.is_file():
            files, explicit = [p], True
        else:
            raise InputError("no such file or directory", str(p))
        for f in files:
            key = f.resolve()
            if key in seen:
                continue
            seen.add(key)
            data = read_toml(f, limits)
            why = _kind(data, not explicit) if isinstance(data, dict) else None
            if why is not None:
                if explicit:
                    raise InputError(f"is {why}, not a scenario; arfem check runs "
                                     "scenario files (see arfem run)", str(f))
                skipped.append(Skipped(str(f), why))
                continue
            if isinstance(data, dict) and "geometry" in data:     # a mesh scenario
                scenarios.append(geometry_case_from_dict(data, str(f), f.parent))
                continue
            scenarios.append(scenario_from_dict(data, str(f), limits))
    if not scenarios:
        raise InputError("no scenario file among them (skipped: " +
                         "; ".join(f"{s.path}: {s.reason}" for s in skipped) + ")",
                         " ".join(str(a) for a in paths))
    return scenarios, skipped


# -- the check -----------------------------------------------------------------------------

def _resolve(cli, file_value, default):
    return cli if cli is not None else (file_value if file_value is not None else default)


def check_scenario(scenario: Scenario, max_abs_pct: float | None = None,
                   max_c1_diff: float | None = None, model: str | None = None,
                   cache: dict | None = None, ar_rod: Rod | None = None) -> ScenarioResult:
    """Run one scenario and hold the chosen AR(1) to both criteria.

    Parameters
    ----------
    scenario : Scenario
    max_abs_pct : float, optional
        Limit on max|AR − FEM| [% of the FEM peak]; None: the scenario's ``[check]``
        value, else 3 %.
    max_c1_diff : float, optional
        Limit on |C1_fitted − C1| [-]; None: the scenario's, else 5e-4.
    model : {"paper", "corrected"}, optional
        The AR(1) checked; None: the scenario's, else "paper".
    cache : dict, optional
        Shared FEM assembly cache (scenarios with the same rod and mesh).
    ar_rod : Rod, optional
        The rod the AR(1) is built from; None: the scenario's rod with its
        ``[check] ar_rod`` values (none: the FEM's own rod).
    """
    from arfem.scenarios.rod.evaluation import evaluate

    lim = scenario.check
    pct = _resolve(max_abs_pct, lim.max_abs_diff_pct_of_peak, DEFAULT_MAX_ABS_PCT)
    dc1 = _resolve(max_c1_diff, lim.max_C1_abs_diff, DEFAULT_MAX_C1_DIFF)
    model = _resolve(model, lim.model, "paper")
    t0 = time.perf_counter()
    ev = evaluate(scenario, cache)
    m = ev.metrics
    ar_rod = scenario.rod.with_(**dict(lim.ar_rod)) if ar_rod is None else ar_rod
    if ar_rod == scenario.rod:          # the AR of the FEM's own physics (computed)
        if model == "paper":
            ar, c1 = ev.ar_growth_um, m["C1"]
        else:
            ar, c1 = ev.ar_corrected_growth_um, m["corrected_C1"]
    else:                               # an AR built from other rod values
        _, ar_m = ar1_on_schedule(ar_rod, scenario.schedule, scenario.dtau_s,
                                  corrected=model == "corrected")
        ar = ar_m * 1e6
        c1 = (c1_paper(ar_rod, scenario.dtau_s) if model == "paper" else
              corrected_coefficients(ar_rod, scenario.dtau_s, 1.0)[0])
    failures = check_ar_tracks_fem(ev.fem_growth_um, ar, m["C1_fitted"], c1,
                                   max_dev_of_peak=pct / 100.0, c1_tol=dc1)
    peak = float(abs(ev.fem_growth_um).max())
    dev_pct = 100.0 * float(abs(ar - ev.fem_growth_um).max()) / peak
    d_c1 = abs(m["C1_fitted"] - c1)
    amp_ok = not any(f.startswith("max|AR") for f in failures)
    c1_ok = not any(f.startswith("|C1_fitted") for f in failures)
    label = "AR" if model == "paper" else "corrected AR"
    crit = [
        Criterion("max_abs_diff_pct_of_peak", dev_pct, pct, "% of the FEM peak", amp_ok,
                  f"max|{label} - FEM| = {dev_pct:.3f} % of the FEM peak "
                  f"({peak:.4g} µm), limit {pct:g} %"),
        Criterion("C1_abs_diff", d_c1, dc1, "-", c1_ok,
                  f"|C1 fitted to FEM - C1 of the {label}| = {d_c1:.3e} "
                  f"({m['C1_fitted']:.6f} vs {c1:.6f}), limit {dc1:.1e}"),
    ]
    return ScenarioResult(scenario.name, scenario.source, model, crit,
                          time.perf_counter() - t0, scenario.rod.biot)


def run_checks(paths, max_abs_pct=None, max_c1_diff=None, model=None, echo=print,
               limits=None):
    """Collect, validate and check every scenario; returns (results, skipped)."""
    if max_abs_pct is not None:
        max_abs_pct = check_limit("max_abs_diff_pct_of_peak", max_abs_pct, "--max-abs-pct")
    if max_c1_diff is not None:
        max_c1_diff = check_limit("max_C1_abs_diff", max_c1_diff, "--max-c1-diff")
    scenarios, skipped = collect(paths, limits)
    for s in skipped:
        echo(f"SKIP {s.path}: {s.reason}")
    cache: dict = {}
    results = []
    with blas_threads():             # small FEMs: threads only contend on a CI machine
        for sc in scenarios:
            r = check_case(sc, max_abs_pct, max_c1_diff, model, cache)
            results.append(r)
            echo(result_line(r))
    return results, skipped


def check_case(case, max_abs_pct: float | None = None, max_c1_diff: float | None = None,
               model: str | None = None, cache: dict | None = None) -> ScenarioResult:
    """Check one collected scenario, the rod's (a :class:`Scenario`:
    :func:`check_scenario`) or a mesh's (a
    :class:`~arfem.scenarios.geometry.check.GeometryCheckCase`); the limits as there
    (``arfem check`` and :func:`arfem.check` both come here)."""
    if isinstance(case, Scenario):
        return check_scenario(case, max_abs_pct, max_c1_diff, model, cache)
    return _check_geometry(case, max_abs_pct, max_c1_diff, model)


def _check_geometry(case, max_abs_pct, max_c1_diff, model) -> ScenarioResult:
    """A mesh scenario (:mod:`arfem.scenarios.geometry.check`); the C1 limit is the rod's."""
    r = check_geometry_case(case, max_abs_pct, model)
    if max_c1_diff is not None:
        r.notes = r.notes + ("--max-c1-diff applies to rod scenarios only",)
    return r
