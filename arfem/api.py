"""arfem's public Python API: what each ``arfem`` command does, as functions.

Everything listed in ``__all__`` here is promised: documented, with units in its
parameter names, an example that runs, and a result object with ``to_dataframe()``
and ``to_json()`` where that helps. It is re-exported lazily by ``import arfem``
(``arfem.solve_fem`` …), so importing arfem stays fast and the FEM, the diagnosis
engine and matplotlib load only when used. Everything else stays importable from its
module but is not promised.

This module sits above every layer (ground → fem → models → scenarios → api): it
composes them, nothing imports it.

Quick start (the FEM and the paper's AR(1) on your own rod in a few lines):

>>> import arfem
>>> rod = arfem.Rod(radius_m=0.05, length_m=0.5)
>>> cycle = arfem.paper_cycle(2000.0)
>>> fem = arfem.solve_fem(rod, cycle, dtau_s=60.0)
>>> ar = arfem.ar1(rod, cycle, dtau_s=60.0)
>>> round(float(fem.growth_um.max()), 2), round(float(ar.growth_um.max()), 2)
(11.06, 10.91)
"""
from __future__ import annotations

import json
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from arfem import __version__
from arfem.io import json_text
from arfem.models.compensator import Compensator, StateSpaceModel, ar1_model
from arfem.params import InputError, Rod, Schedule, paper_cycle

__all__ = ["Rod", "Schedule", "paper_cycle", "load_scenario", "solve_fem", "FemResult",
           "ar1", "AR1Result", "compare", "Comparison", "check", "CheckResult", "sweep",
           "diagnose", "DiagnosisResult", "Compensator", "StateSpaceModel", "ar1_model",
           "read_model", "InputError", "__version__"]


def _frame(columns: dict):
    import pandas as pd
    return pd.DataFrame(columns)


def load_scenario(path):
    """Read and validate a scenario TOML (or a built-in name such as ``"paper_fig2"``).

    Parameters
    ----------
    path : str or path-like
        A scenario file (see the documentation's "Scenario files" page) or the name of a
        built-in paper scenario: ``"paper_fig2"`` (q = 2000 W/m²), ``"paper_fig3"``
        (3000 W/m²).

    Returns
    -------
    arfem.scenarios.config.Scenario
        Validated: ``rod``, ``schedule``, ``dtau_s`` [s], ``fem`` settings, outputs.

    Raises
    ------
    InputError
        Malformed file, unknown key or impossible value; the message names the file
        and the key.

    Examples
    --------
    >>> sc = load_scenario("paper_fig2")
    >>> sc.dtau_s, sc.schedule.total_s / 3600
    (30.0, 24.0)
    """
    from arfem.scenarios.config import load_scenario as _load
    return _load(path)


# -- the FEM -------------------------------------------------------------------------------

@dataclass(frozen=True)
class FemResult:
    """Axial growth of the FEM rod at the AR sample times.

    Attributes
    ----------
    times_s : ndarray
        0, Δτ, 2Δτ, … [s].
    growth_um : ndarray
        Axial growth α∫θ dV / A [µm] (the far-face growth of a free rod).
    heat_J : ndarray
        Heat stored in the rod relative to the ambient state [J].
    model : str
        ``"axisymmetric"`` or ``"3d"``.
    solver : str
        ``"modal"`` (exact in time; reduced-modal on 3D), ``"crank-nicolson"`` or
        ``"backward-euler"``.
    ndofs : int
        FEM unknowns.
    error_estimate_um : ndarray or None
        The reduced-modal solve's stated error [µm] (3D modal only).
    """

    times_s: np.ndarray
    growth_um: np.ndarray
    heat_J: np.ndarray
    model: str
    solver: str
    ndofs: int
    error_estimate_um: np.ndarray | None = None

    def to_dataframe(self):
        """``time_s``, ``growth_um``, ``heat_J`` as a pandas DataFrame."""
        return _frame({"time_s": self.times_s, "growth_um": self.growth_um,
                       "heat_J": self.heat_J})

    def to_json(self) -> str:
        """The result as a JSON document (arrays as lists)."""
        return json_text(self.__dict__)


def solve_fem(rod: Rod, schedule: Schedule, *, dtau_s: float = 30.0,
              model: str = "axisymmetric", order: int = 2, solver: str = "modal",
              dt_s: float | None = None, mesh: dict | None = None) -> FemResult:
    """Run the transient heat FEM of the rod over a duty cycle; growth every Δτ.

    Parameters
    ----------
    rod : Rod
        Geometry [m], material and nominal convection h [W/(m²·K)] and ambient [°C].
    schedule : Schedule
        Piecewise-constant heat flux q [W/m²] (and optionally ambient [°C], h) per
        segment; every segment must be a multiple of ``dtau_s``.
    dtau_s : float
        Output interval Δτ [s].
    model : {"axisymmetric", "3d"}
        Axisymmetric Q1/Q2 quadrilaterals, or 3D bricks (order 2 = the paper's 20-node).
    order : {1, 2}
        Element order.
    solver : {"modal", "crank-nicolson", "backward-euler"}
        ``"modal"``: exact in time (reduced-modal with a stated error on 3D).
    dt_s : float, optional
        θ-method step [s]; must divide ``dtau_s`` (default ``dtau_s``).
    mesh : dict, optional
        Mesh counts (axisymmetric ``nr``, ``nz``; 3D ``n_core``, ``n_ring``, ``nz``).

    Returns
    -------
    FemResult

    Examples
    --------
    >>> r = solve_fem(Rod(), paper_cycle(2000.0))
    >>> r.ndofs, round(float(r.growth_um.max()), 3)
    (441, 22.167)
    """
    from arfem.fem.heat import build_3d, build_axisymmetric, solve_modal, solve_theta
    thetas = {"modal": None, "crank-nicolson": 0.5, "backward-euler": 1.0}
    if solver not in thetas:
        raise InputError(f"must be one of {sorted(thetas)}, got {solver!r}", "solver")
    if model not in ("axisymmetric", "3d"):
        raise InputError(f"must be 'axisymmetric' or '3d', got {model!r}", "model")
    build = build_axisymmetric if model == "axisymmetric" else build_3d
    fem = build(rod, order=order, **(mesh or {}))
    fine = schedule.subdivided(dtau_s)
    if thetas[solver] is None:
        res = solve_modal(fem, fine)
        est = getattr(res, "error_estimate_m", None)
        return FemResult(res.times_s, res.growth_um, res.heat_J, model, solver, fem.ndofs,
                         None if est is None else est * 1e6)
    dt = dtau_s if dt_s is None else float(dt_s)
    k = dtau_s / dt
    if abs(k - round(k)) > 1e-9:
        raise InputError(f"must divide dtau_s = {dtau_s:g} s, got {dt:g}", "dt_s")
    res = solve_theta(fem, fine.subdivided(dt), dt, theta=thetas[solver])
    pick = slice(None, None, int(round(k)))
    return FemResult(res.times_s[pick], res.growth_um[pick], res.heat_J[pick], model,
                     solver, fem.ndofs)


# -- the AR(1) ------------------------------------------------------------------------------

@dataclass(frozen=True)
class AR1Result:
    """The AR(1) growth ΔL_n = C1 ΔL_{n−1} + C2(q_n) (paper eq. 12) on a schedule.

    Attributes
    ----------
    times_s : ndarray
        0, Δτ, 2Δτ, … [s].
    growth_um : ndarray
        ΔL [µm].
    C1 : float
        e^{−bΔτ} (paper eq. 13), or the corrected model's slowest-radial-mode value.
    C2_um_per_W_m2 : float
        C2 per unit heat flux [µm per W/m²] (paper eq. 14 is linear in q).
    corrected : bool
        True for the radial-mode corrected AR(1).
    """

    times_s: np.ndarray
    growth_um: np.ndarray
    C1: float
    C2_um_per_W_m2: float
    corrected: bool

    def to_dataframe(self):
        """``time_s``, ``growth_um`` as a pandas DataFrame."""
        return _frame({"time_s": self.times_s, "growth_um": self.growth_um})

    def to_json(self) -> str:
        """The result as a JSON document (arrays as lists)."""
        return json_text(self.__dict__)


def ar1(rod: Rod, schedule: Schedule, *, dtau_s: float = 30.0,
        corrected: bool = False) -> AR1Result:
    """The closed-form AR(1) thermal-growth model (paper eqs. 12–14) on a duty cycle.

    Parameters
    ----------
    rod : Rod
        Supplies a = λ/(ρc), b = 2h/(ρcR) and α.
    schedule : Schedule
        Heat flux q [W/m²] per segment; every segment a multiple of ``dtau_s``.
    dtau_s : float
        AR step Δτ [s].
    corrected : bool
        Use arfem's radial-mode corrected C1, C2 (derived from the 3D rod's slowest
        axially uniform mode; reduces to eqs. 13–14 as the Biot number → 0).

    Returns
    -------
    AR1Result

    Examples
    --------
    >>> r = ar1(Rod(), paper_cycle(2000.0))
    >>> round(r.C1, 4), round(r.C2_um_per_W_m2 * 2000, 4)
    (0.9909, 0.1985)
    """
    from arfem.models.ar1 import ar1_on_schedule, c1_paper, c2_paper, corrected_coefficients
    t, g = ar1_on_schedule(rod, schedule, dtau_s, corrected=corrected)
    if corrected:
        c1, c2 = corrected_coefficients(rod, dtau_s, 1.0)
    else:
        c1, c2 = c1_paper(rod, dtau_s), c2_paper(rod, dtau_s, 1.0)
    return AR1Result(t, g * 1e6, float(c1), float(c2) * 1e6, corrected)


# -- FEM against AR(1), and the gate ----------------------------------------------------------

@dataclass(frozen=True)
class Comparison:
    """FEM, paper AR(1) and corrected AR(1) on one scenario (what ``arfem run`` computes).

    Attributes
    ----------
    times_s : ndarray
        Sample times [s].
    fem_um, ar_um, ar_corrected_um : ndarray
        Growths [µm].
    metrics : dict
        Every figure of ``summary.json`` (C1, C2, max|AR − FEM| in µm and % of the peak,
        the fitted C1, …), units in the keys.
    """

    times_s: np.ndarray
    fem_um: np.ndarray
    ar_um: np.ndarray
    ar_corrected_um: np.ndarray
    metrics: dict = field(repr=False)

    def to_dataframe(self):
        """``time_s``, ``fem_um``, ``ar_um``, ``ar_corrected_um`` as a DataFrame."""
        return _frame({"time_s": self.times_s, "fem_um": self.fem_um, "ar_um": self.ar_um,
                       "ar_corrected_um": self.ar_corrected_um})

    def to_json(self) -> str:
        """The metrics as a JSON document (the series are in :meth:`to_dataframe`)."""
        return json_text(self.metrics)


def _scenario(scenario):
    from arfem.scenarios.config import Scenario
    return scenario if isinstance(scenario, Scenario) else load_scenario(scenario)


def compare(scenario) -> Comparison:
    """Run the FEM and both AR(1) models on a scenario and compare them (``arfem run``,
    without writing files).

    Parameters
    ----------
    scenario : Scenario, str or path-like
        A loaded scenario, a scenario file, or ``"paper_fig2"``/``"paper_fig3"``.

    Returns
    -------
    Comparison

    Examples
    --------
    >>> c = compare("paper_fig2")
    >>> round(c.metrics["max_abs_diff_pct_of_peak"], 2)
    2.57
    """
    from arfem.scenarios.run import evaluate
    ev = evaluate(_scenario(scenario))
    return Comparison(ev.times_s, ev.fem_growth_um, ev.ar_growth_um,
                      ev.ar_corrected_growth_um, dict(ev.metrics))


@dataclass(frozen=True)
class CheckResult:
    """``arfem check`` on one scenario: each criterion with its value and limit.

    Attributes
    ----------
    passed : bool
        Every criterion holds.
    criteria : list of dict
        ``name``, ``value``, ``limit``, ``unit``, ``passed``, ``message``.
    """

    scenario: str
    passed: bool
    criteria: list

    def to_json(self) -> str:
        """The result as a JSON document."""
        return json_text(self.__dict__)


def check(scenario, *, max_abs_pct: float | None = None, max_c1_diff: float | None = None,
          model: str | None = None) -> CheckResult:
    """Does the AR(1) track the FEM on this scenario? (``arfem check``, one scenario.)

    Parameters
    ----------
    scenario : Scenario, str or path-like
    max_abs_pct : float, optional
        Limit on max|AR − FEM| [% of the FEM peak]; default the scenario's ``[check]``
        value, else 3 %.
    max_c1_diff : float, optional
        Limit on the absolute difference of C1 fitted to the FEM and the AR's C1 [-];
        default 5e-4.
    model : {"paper", "corrected"}, optional
        Which AR(1) is held to the limits; default the paper's.

    Returns
    -------
    CheckResult

    Examples
    --------
    >>> r = check("paper_fig2")
    >>> r.passed, [c["name"] for c in r.criteria]
    (True, ['max_abs_diff_pct_of_peak', 'C1_abs_diff'])
    """
    from arfem.scenarios.check import check_scenario
    from arfem.scenarios.config import check_limit
    if max_abs_pct is not None:
        max_abs_pct = check_limit("max_abs_diff_pct_of_peak", max_abs_pct, "max_abs_pct")
    if max_c1_diff is not None:
        max_c1_diff = check_limit("max_C1_abs_diff", max_c1_diff, "max_c1_diff")
    r = check_scenario(_scenario(scenario), max_abs_pct, max_c1_diff, model)
    return CheckResult(r.scenario, r.passed, [dict(c.__dict__) for c in r.criteria])


def sweep(sweep_toml, out, *, workers: int | None = None, force: bool = False,
          progress: bool = False):
    """Run a parameter sweep file into ``out`` (``arfem sweep``; resumable).

    Parameters
    ----------
    sweep_toml : str or path-like
        A sweep file (``[sweep]`` with ``base`` and a ``[sweep.grid]`` of scenario keys).
    out : str or path-like
        Output folder (``results.csv``, figures, ``report.html``); the ``--out`` rules
        apply: arfem never replaces a file it did not write.
    workers : int, optional
        Local processes (default: the cores, 1 = in-process).
    force : bool
        Recompute every point.
    progress : bool
        Show a progress bar.

    Returns
    -------
    arfem.scenarios.sweep.runner.RunReport
        ``n_points``, ``n_computed``, ``n_failed``, ``wall_s``, …

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (d / "s.toml").write_text(
    ...     '[sweep]\\nname = "demo"\\nbase = "paper_fig2"\\n'
    ...     '[sweep.grid]\\nh_W_m2K = [35, 55]\\n')
    >>> rep = sweep(d / "s.toml", d / "out", workers=1)
    >>> rep.n_points, rep.n_failed
    (2, 0)
    """
    from arfem.scenarios.sweep import load_sweep, run_sweep
    return run_sweep(load_sweep(sweep_toml), out, workers=workers, force=force,
                     progress=progress)


# -- diagnosis of measured data ---------------------------------------------------------------

@dataclass(frozen=True)
class DiagnosisResult:
    """What ``arfem diagnose`` finds in a record.

    Attributes
    ----------
    cause : str
        The named cause (``"none"`` when the simulation's model explains the record).
    summary : dict
        The ``diagnosis.json`` document of ``docs/measured-data.md`` (causes,
        parameters with 95 % intervals, hold-out RMSEs of the baseline, the extended
        model and the MLR, warnings).
    series : dict
        Arrays behind the figures: time, measured and predicted growths [µm].
    """

    cause: str
    summary: dict = field(repr=False)
    series: dict = field(repr=False)

    def to_dataframe(self):
        """The equal-length arrays of ``series`` as a pandas DataFrame."""
        n = len(self.series.get("time_s", ()))
        return _frame({k: np.asarray(v) for k, v in self.series.items()
                       if np.ndim(v) == 1 and len(v) == n})

    def to_json(self) -> str:
        """``diagnosis.json`` as a string."""
        return json_text(self.summary)


def _write_contract(df, folder: Path, rod: Rod | None, name: str, initial: str) -> Path:
    """A DataFrame as a measured-data contract pair (CSV + TOML) in ``folder``."""
    import csv
    cols = [str(c) for c in df.columns]
    with open(folder / "data.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for row in df.itertuples(index=False):
            w.writerow(["" if (isinstance(v, float) and np.isnan(v)) else repr(float(v))
                        if isinstance(v, (float, np.floating)) else v for v in row])
    lines = ["[dataset]", f"name = {json.dumps(name)}", 'csv = "data.csv"',
             f"initial = {json.dumps(initial)}"]
    if rod is not None:
        from arfem.scenarios.dataset import ROD_KEYS
        lines.append("[rod]")
        lines += [f"{k} = {float(getattr(rod, k))!r}" for k in ROD_KEYS]
    toml = folder / "data.toml"
    toml.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return toml


def diagnose(data, *, rod: Rod | None = None, holdout_start_s: float | None = None,
             initial: str = "equilibrium", name: str = "dataframe",
             frame_search: str = "narrow", progress=False) -> DiagnosisResult:
    """What does the simulation get wrong on a measured record, and why?

    Parameters
    ----------
    data : pandas.DataFrame, dict of columns, or path-like
        A record with the columns of ``docs/measured-data.md``: ``time_s`` [s],
        ``growth_um`` [µm], and ``q_W_m2`` [W/m²] or ``speed_rpm`` [1/min]; optional
        ``ambient_C`` [°C] and ``T_<name>_C`` [°C]. A path is a contract TOML file.
    rod : Rod, optional
        The rod the simulation assumes (default: the seed paper's); not with a path.
    holdout_start_s : float, optional
        Start of the hold-out [s] (default: the last third of the record).
    initial : {"equilibrium", "unknown"}
        ``"unknown"`` when the record did not start at equilibrium with the ambient.
    name : str
        The record's name in the result.
    frame_search : {"narrow", "wide", "average"}
        Speed-only records: frame structures compared (see ``arfem diagnose --help``).
    progress : bool or callable
        True: show the step under way and the elapsed time on stderr (a real record
        takes seconds to a minute); a callable is called with each step's name instead.

    Returns
    -------
    DiagnosisResult

    Raises
    ------
    InputError
        A missing column, a unit that cannot be right, NaNs in time or input; for a
        DataFrame the message names ``<DataFrame>`` and the column or row.

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> cycle = Schedule([4 * 3600.0] * 6, [2000.0, 0.0] * 3)      # 24 h, on/off
    >>> truth = solve_fem(Rod(convection_W_m2K=80.0), cycle, dtau_s=300.0)
    >>> noise = np.random.default_rng(1).normal(0.0, 0.02, truth.times_s.size)
    >>> df = pd.DataFrame({"time_s": truth.times_s,
    ...                    "q_W_m2": np.r_[0.0, cycle.subdivided(300.0).q_W_m2],
    ...                    "growth_um": truth.growth_um + noise})
    >>> d = diagnose(df)             # the simulation assumes the paper's h = 55 W/(m²K)
    >>> d.cause, round(d.summary["causes"][0]["parameters"]["h_W_m2K"])
    ('convection_mismatch', 80)
    """
    from arfem.scenarios.diagnose import diagnose_file
    if not callable(progress):
        from arfem.scenarios.progress import Progress
        # asked for: shown even where stderr is no terminal (a notebook's)
        with Progress(12, "arfem.diagnose", enabled=bool(progress), tty=True) as bar:
            return diagnose(data, rod=rod, holdout_start_s=holdout_start_s, initial=initial,
                            name=name, frame_search=frame_search, progress=bar)
    if isinstance(data, (str, Path)):
        if rod is not None:
            raise InputError("give the rod in the dataset TOML's [rod] table, not here", "rod")
        d = diagnose_file(data, holdout_start_s, frame_search, progress)
        return DiagnosisResult(str(d.summary.get("cause", "")), d.summary, d.series)
    if isinstance(data, dict):
        data = _frame(data)
    if initial not in ("equilibrium", "unknown"):
        raise InputError(f"must be 'equilibrium' or 'unknown', got {initial!r}", "initial")
    with tempfile.TemporaryDirectory(prefix="arfem-df-") as tmp:
        toml = _write_contract(data, Path(tmp), rod, name, initial)
        try:
            d = diagnose_file(toml, holdout_start_s, frame_search, progress)
        except InputError as exc:
            msg = str(exc).replace(str(Path(tmp) / "data.csv"), "<DataFrame>")
            raise InputError(msg.replace(str(toml), "<DataFrame>")) from None
    return DiagnosisResult(str(d.summary.get("cause", "")), d.summary, d.series)


def read_model(path) -> StateSpaceModel:
    """Read and validate a ``model.json`` (written by ``arfem run``) for a compensator.

    Parameters
    ----------
    path : str or path-like
        The file (layout: the documentation's "model.json" page).

    Returns
    -------
    StateSpaceModel

    Raises
    ------
    InputError
        Not JSON, another ``model_version``, a wrong shape, a model that would not settle.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "model.json"
    >>> _ = p.write_text(json.dumps(ar1_model(0.99, 1e-4, dtau_s=30.0).to_dict()))
    >>> read_model(p).dtau_s, read_model(p).inputs[0].name
    (30.0, 'q_W_m2')
    """
    from arfem.scenarios.model_file import read_model as _read
    return _read(path)
