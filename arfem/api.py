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

import dataclasses
import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from arfem import __version__
from arfem.io import json_text
from arfem.models.compensator import Compensator, StateSpaceModel, ar1_model
from arfem.params import InputError, Rod, Schedule, paper_cycle

if TYPE_CHECKING:                     # names in annotations only; not loaded at import
    import pandas
    from numpy.typing import ArrayLike

    from arfem.models.diagnosis.dataset import Dataset
    from arfem.models.geodiagnosis.engine import GeoDiagnosis
    from arfem.scenarios.checking import Criterion
    from arfem.scenarios.config import Scenario
    from arfem.scenarios.sweep.runner import RunReport

__all__ = ["Rod", "Schedule", "paper_cycle", "load_scenario", "solve_fem", "FemResult",
           "ar1", "AR1Result", "compare", "Comparison", "check", "CheckResult", "sweep",
           "diagnose", "DiagnosisResult", "Compensator", "StateSpaceModel", "ar1_model",
           "read_model", "read_record", "Record", "InputError", "__version__"]


def _frame(columns: dict) -> pandas.DataFrame:
    import pandas as pd
    return pd.DataFrame(columns)


def load_scenario(path: str | Path) -> Scenario:
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

    def to_dataframe(self) -> pandas.DataFrame:
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
    r"""The paper's AR(1) growth on a duty cycle, with its two coefficients.

    The growth follows :math:`\Delta L_n = C_1 \Delta L_{n-1} + C_2(q_n)` (paper
    equation 12).

    Attributes
    ----------
    times_s : ndarray
        0, Δτ, 2Δτ, … [s].
    growth_um : ndarray
        ΔL [µm].
    C1 : float
        :math:`e^{-b\Delta\tau}` (paper eq. 13), or the corrected model's value from the
        slowest radial mode.
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

    def to_dataframe(self) -> pandas.DataFrame:
        """``time_s``, ``growth_um`` as a pandas DataFrame."""
        return _frame({"time_s": self.times_s, "growth_um": self.growth_um})

    def to_json(self) -> str:
        """The result as a JSON document (arrays as lists)."""
        return json_text(self.__dict__)


def ar1(rod: Rod, schedule: Schedule, *, dtau_s: float = 30.0,
        corrected: bool = False) -> AR1Result:
    """Run the paper's closed-form AR(1) thermal-growth model on a duty cycle.

    The model is equations 12–14 of Du et al. (2021); ``corrected=True`` runs arfem's
    radial-mode corrected coefficients instead.

    Parameters
    ----------
    rod : Rod
        Supplies a = λ/(ρc), b = 2h/(ρcR) and α (the thermal expansion coefficient).
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

    def to_dataframe(self) -> pandas.DataFrame:
        """``time_s``, ``fem_um``, ``ar_um``, ``ar_corrected_um`` as a DataFrame."""
        return _frame({"time_s": self.times_s, "fem_um": self.fem_um, "ar_um": self.ar_um,
                       "ar_corrected_um": self.ar_corrected_um})

    def to_json(self) -> str:
        """The metrics as a JSON document (the series are in :meth:`to_dataframe`)."""
        return json_text(self.metrics)


def _scenario(scenario: Scenario | str | Path) -> Scenario:
    from arfem.scenarios.config import Scenario
    return scenario if isinstance(scenario, Scenario) else load_scenario(scenario)


def compare(scenario: Scenario | str | Path) -> Comparison:
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
    from arfem.scenarios.evaluation import evaluate
    ev = evaluate(_scenario(scenario))
    return Comparison(ev.times_s, ev.fem_growth_um, ev.ar_growth_um,
                      ev.ar_corrected_growth_um, dict(ev.metrics))


@dataclass(frozen=True)
class CheckResult:
    """``arfem check`` on one scenario: each criterion with its value and limit.

    Attributes
    ----------
    scenario : str
        The scenario's name.
    passed : bool
        Every criterion holds.
    criteria : tuple of arfem.scenarios.checking.Criterion
        Each criterion (frozen): ``name``, ``value`` against ``limit`` (in ``unit``),
        ``passed``, and the ``message`` ``arfem check`` prints.
    """

    scenario: str
    passed: bool
    criteria: tuple[Criterion, ...]

    def to_json(self) -> str:
        """The result as a JSON document: ``scenario``, ``passed`` and each criterion's
        fields, as in ``arfem check --json``)."""
        return json_text({"scenario": self.scenario, "passed": self.passed,
                          "criteria": [dataclasses.asdict(c) for c in self.criteria]})


def check(scenario: Scenario | str | Path, *, max_abs_pct: float | None = None, max_c1_diff: float | None = None,
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
        Which AR(1) is held to the limits; default the paper's. On a mesh scenario
        (a file with ``[geometry]``): "corrected" (default) is the slowest-mode AR(1),
        "paper" the lumped one, held per displacement sensor
        (:mod:`arfem.scenarios.geometry_check`; the C1 limit does not apply).

    Returns
    -------
    CheckResult

    Examples
    --------
    >>> r = check("paper_fig2")
    >>> r.passed, [c.name for c in r.criteria]
    (True, ['max_abs_diff_pct_of_peak', 'C1_abs_diff'])
    """
    from arfem.scenarios.checking import check_scenario
    from arfem.scenarios.config import check_limit
    if max_abs_pct is not None:
        max_abs_pct = check_limit("max_abs_diff_pct_of_peak", max_abs_pct, "max_abs_pct")
    if max_c1_diff is not None:
        max_c1_diff = check_limit("max_C1_abs_diff", max_c1_diff, "max_c1_diff")
    from arfem.scenarios.geometry_scenario import is_geometry_scenario
    if isinstance(scenario, (str, Path)) and is_geometry_scenario(scenario):
        # a mesh scenario (issue 32 item 4): the AR(1)s of any geometry, per sensor
        from arfem.scenarios.geometry_check import check_geometry_case, load_geometry_case
        r = check_geometry_case(load_geometry_case(scenario), max_abs_pct, model)
    else:
        r = check_scenario(_scenario(scenario), max_abs_pct, max_c1_diff, model)
    return CheckResult(r.scenario, r.passed, tuple(r.criteria))


def sweep(sweep_toml: str | Path, out: str | Path, *, workers: int | None = None,
          force: bool = False, progress: bool = False) -> RunReport:
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

class NamedCause(NamedTuple):
    """One cause a diagnosis names (an entry of diagnosis.json's ``causes``).

    Attributes
    ----------
    cause : str
        The cause, one of the contract's vocabulary (``"convection_mismatch"``, ...).
    parameters : dict of str to float
        Its contract parameters, each named with its unit (``h_W_m2K`` [W/(m²·K)], ...).
    ci95 : dict of str to tuple of float
        Their 95 % intervals (low, high) [the parameter's unit].
    """

    cause: str
    parameters: dict
    ci95: dict


class HoldoutScore(NamedTuple):
    """How the baseline and the extended model score on the hold-out (diagnosis.json's
    ``holdout``).

    Attributes
    ----------
    start_s : float
        Start of the hold-out [s].
    baseline_rmse_um, extended_rmse_um : float
        RMSE of each on the hold-out [µm].
    gain_pct : float
        1 − extended/baseline RMSE [%].
    n_samples : int
        Hold-out samples scored.
    """

    start_s: float
    baseline_rmse_um: float
    extended_rmse_um: float
    gain_pct: float
    n_samples: int


class DiagnosisSeries(NamedTuple):
    """The arrays behind a diagnosis's figures, each of shape (N,).

    Attributes
    ----------
    time_s : ndarray
        Sample times [s].
    growth_um : ndarray
        Measured growth [µm] (NaN where not observed).
    baseline_um, extended_um : ndarray
        The baseline's and the extended model's growth [µm].
    outlier : ndarray
        1.0 on rows left out of the fit and the scores (outliers, unobserved), else 0.0.
    mlr_um : ndarray or None
        Paper eq. 18 on the recorded temperatures [µm] (None without thermometers).
    """

    time_s: np.ndarray
    growth_um: np.ndarray
    baseline_um: np.ndarray
    extended_um: np.ndarray
    outlier: np.ndarray
    mlr_um: np.ndarray | None


@dataclass(frozen=True)
class DiagnosisResult:
    """What ``arfem diagnose`` finds in a record.

    ``summary`` and ``series`` are the documents the command writes (diagnosis.json,
    series.csv); ``verdict``, ``causes``, ``holdout``, ``warnings`` and ``arrays`` read
    the same values typed.

    Attributes
    ----------
    cause : str
        The named cause (``"none"`` when the simulation's model explains the record).
    summary : dict
        The ``diagnosis.json`` document of ``docs/measured-data.md`` (causes,
        parameters with 95 % intervals, hold-out RMSEs of the baseline, the extended
        model and the MLR, warnings).
    series : dict
        Arrays behind the figures: time, measured and predicted growths [µm], and the
        recorded signals by column.
    """

    cause: str
    summary: dict = field(repr=False)
    series: dict = field(repr=False)

    @property
    def verdict(self) -> str:
        """``established``, ``unconfirmed``, ``explained`` or ``not_explained``."""
        return str(self.summary.get("verdict", ""))

    @property
    def causes(self) -> tuple[NamedCause, ...]:
        """The causes named, with their parameters and 95 % intervals (empty if none)."""
        return tuple(NamedCause(c["cause"], dict(c["parameters"]),
                                {k: tuple(v) for k, v in c["ci95"].items()})
                     for c in self.summary.get("causes", ()))

    @property
    def holdout(self) -> HoldoutScore:
        """The hold-out scores of the baseline and the extended model."""
        h = self.summary["holdout"]
        return HoldoutScore(float(h["start_s"]), float(h["baseline_rmse_um"]),
                            float(h["extended_rmse_um"]), float(h["gain_pct"]),
                            int(h["n_samples"]))

    @property
    def warnings(self) -> tuple[str, ...]:
        """What a reader of the result must not miss."""
        return tuple(self.summary.get("warnings", ()))

    @property
    def arrays(self) -> DiagnosisSeries:
        """The measured and predicted growths of ``series``, typed."""
        s = self.series
        return DiagnosisSeries(*(np.asarray(s[k]) for k in (
            "time_s", "growth_um", "baseline_um", "extended_um", "outlier")),
            None if s.get("mlr_um") is None else np.asarray(s["mlr_um"]))

    def to_dataframe(self) -> pandas.DataFrame:
        """The equal-length arrays of ``series`` as a pandas DataFrame."""
        n = len(self.series.get("time_s", ()))
        return _frame({k: np.asarray(v) for k, v in self.series.items()
                       if np.ndim(v) == 1 and len(v) == n})

    def to_json(self) -> str:
        """``diagnosis.json`` as a string."""
        return json_text(self.summary)


#: The unit of each contract column (``T_<name>_C`` columns are °C).
_UNITS = {"time_s": "s", "growth_um": "µm", "q_W_m2": "W/m²", "speed_rpm": "1/min",
          "ambient_C": "°C"}


@dataclass(frozen=True)
class Record:
    """A measured record read by :func:`read_record`: its samples and what its TOML says.

    Attributes
    ----------
    data : pandas.DataFrame
        One row per kept sample, columns under the contract's names: ``time_s`` [s],
        ``growth_um`` [µm], ``q_W_m2`` [W/m²] and/or ``speed_rpm`` [1/min], and where
        recorded ``ambient_C`` [°C] and ``T_<name>_C`` [°C] (NaN where a cell was empty).
    name : str
        ``[dataset] name``.
    initial : str
        ``"equilibrium"`` or ``"unknown"`` (``[dataset] initial``): did the record start
        at equilibrium with the ambient? :func:`diagnose` uses it.
    units : dict of str to str
        The unit of each column of ``data``.
    rod : Rod
        The rod the simulation assumes (``[rod]``, the seed paper's where not given).
    source : pathlib.Path
        The TOML file.
    csv_path : pathlib.Path
        The CSV file it names.
    columns : dict of str to str
        Contract name to the CSV's own column name (``[columns]``; the identity where the
        CSV already uses the contract's name).
    sensors : dict of str to str
        ``[sensors.<column>] description``.
    notes : tuple of str
        What the reader did (rows dropped, gaps filled, outliers flagged) and noticed.
    """

    data: pandas.DataFrame = field(repr=False)
    name: str
    initial: str
    units: dict
    rod: Rod = field(repr=False)
    source: Path
    csv_path: Path
    columns: dict = field(repr=False)
    sensors: dict = field(repr=False)
    notes: tuple = field(repr=False)
    _dataset: Dataset = field(repr=False, compare=False)

    def to_dataframe(self) -> pandas.DataFrame:
        """The samples (:attr:`data`, a copy) as a pandas DataFrame."""
        return self.data.copy()


def _record_frame(ds):
    """A loaded :class:`~arfem.models.diagnosis.dataset.Dataset` as a DataFrame."""
    cols = {"time_s": ds.time_s, "growth_um": ds.growth_um}
    for key in ("q_W_m2", "speed_rpm", "ambient_C"):
        if getattr(ds, key) is not None:
            cols[key] = getattr(ds, key)
    cols.update(ds.temperatures)
    return _frame({k: np.array(v, dtype=float) for k, v in cols.items()})


def read_record(path: str | Path) -> Record:
    """Read a measured record (a contract TOML and the CSV it names) into a DataFrame.

    The CSV's own column names are mapped onto the contract's by the TOML's
    ``[columns]`` table, and every check of ``docs/measured-data.md`` is applied (the
    same reading as ``arfem diagnose``).

    Parameters
    ----------
    path : str or path-like
        The record's TOML file (``[dataset]``, ``[rod]``, ``[columns]``, ``[sensors.*]``).

    Returns
    -------
    Record
        ``data`` (the samples under the contract's names) and the metadata: ``initial``,
        ``units``, ``rod``, ``source``, ``csv_path``, ``columns``, ``sensors``, ``notes``.

    Raises
    ------
    InputError
        A malformed TOML or CSV; the message names the file, the key or line, and what
        is wrong.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (d / "r.csv").write_text("t,g,q\\n0,0,0\\n30,0.2,2000\\n60,0.4,2000\\n")
    >>> _ = (d / "r.toml").write_text('[dataset]\\ninitial = "unknown"\\n'
    ...                               '[columns]\\ntime_s = "t"\\ngrowth_um = "g"\\nq_W_m2 = "q"\\n')
    >>> rec = read_record(d / "r.toml")
    >>> rec.initial, list(rec.data.columns), rec.units["q_W_m2"]
    ('unknown', ['time_s', 'growth_um', 'q_W_m2'], 'W/m²')
    """
    from arfem.scenarios.dataset import load_dataset, read_record_doc
    from arfem.scenarios.georecord import refuse_mesh_channels, refuse_mesh_record
    doc = read_record_doc(path)          # the TOML, read once
    refuse_mesh_record(doc)              # contract v3: the mesh's diagnosis, not this
    ds = load_dataset(doc)
    refuse_mesh_channels(ds)
    frame = _record_frame(ds)
    mapping = doc.mapping
    columns = {c: mapping.get(c, c) for c in frame.columns}
    units = {c: _UNITS.get(c, "°C") for c in frame.columns}
    return Record(frame, ds.name, "equilibrium" if ds.initial_known else "unknown", units,
                  ds.rod, Path(path), ds.csv_path, columns, dict(ds.sensors),
                  tuple(ds.notes), ds)


def _initial_of(given: str | None, recorded: str, where: str) -> str:
    """The record's ``initial``; an explicit value must not contradict it."""
    if given is not None and given != recorded:
        raise InputError(f"initial={given!r} contradicts the record's initial = "
                         f"{recorded!r}; change [dataset] initial in the TOML instead",
                         where)
    return recorded


def diagnose(data: Record | str | Path | pandas.DataFrame | Mapping[str, ArrayLike], *,
             rod: Rod | None = None, holdout_start_s: float | None = None,
             initial: str | None = None, name: str = "dataframe",
             frame_search: str = "narrow",
             progress: bool | Callable[[str], None] = False) -> DiagnosisResult:
    """What does the simulation get wrong on a measured record, and why?

    Parameters
    ----------
    data : Record, path-like, pandas.DataFrame or dict of columns
        A :class:`Record` from :func:`read_record`; the path of a contract TOML file (as
        ``arfem diagnose`` takes); or the samples, with the columns of
        ``docs/measured-data.md``: ``time_s`` [s], ``growth_um`` [µm], and ``q_W_m2``
        [W/m²] or ``speed_rpm`` [1/min]; optional ``ambient_C`` [°C] and ``T_<name>_C``
        [°C] (NaN = an empty cell). Samples are validated in memory, no file is written.
    rod : Rod, optional
        The rod the simulation assumes (default: the seed paper's); only with samples
        (a TOML's rod is its ``[rod]`` table).
    holdout_start_s : float, optional
        Start of the hold-out [s] (default: the last third of the record).
    initial : {"equilibrium", "unknown"}, optional
        Did the record start at equilibrium with the ambient? A TOML or a
        :class:`Record` states it (``[dataset] initial``), and a value given here must
        agree with it. For samples the default is ``"equilibrium"``, and the result's
        warnings say it was assumed.
    name : str
        The record's name in the result (samples only).
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
        A missing column, a unit that cannot be right, NaNs in time or input; for
        samples the message names ``<DataFrame>``, the row (from 0) and the column.

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> cycle = Schedule([4 * 3600.0] * 6, [2000.0, 0.0] * 3)      # 24 h, on/off
    >>> truth = solve_fem(Rod(convection_W_m2K=80.0), cycle, dtau_s=300.0)
    >>> noise = np.random.default_rng(1).normal(0.0, 0.02, truth.times_s.size)
    >>> df = pd.DataFrame({"time_s": truth.times_s,
    ...                    "q_W_m2": np.r_[0.0, cycle.subdivided(300.0).q_W_m2],
    ...                    "growth_um": truth.growth_um + noise})
    >>> d = diagnose(df, initial="equilibrium")   # the simulation assumes h = 55 W/(m²K)
    >>> d.cause, round(d.summary["causes"][0]["parameters"]["h_W_m2K"])
    ('convection_mismatch', 80)
    """
    from arfem.models.diagnosis.engine import diagnose as _diagnose
    if not callable(progress):
        from arfem.scenarios.progress import Progress
        # asked for: shown even where stderr is no terminal (a notebook's)
        with Progress(12, "arfem.diagnose", enabled=bool(progress), tty=True) as bar:
            return diagnose(data, rod=rod, holdout_start_s=holdout_start_s, initial=initial,
                            name=name, frame_search=frame_search, progress=bar)
    progress("reading the dataset")
    ds, assumed = _dataset_of(data, rod, initial, name)
    d = _diagnose(ds, holdout_start_s, frame_search, progress)
    summary = d.summary
    if assumed:
        summary = {**summary, "warnings": [*summary.get("warnings", []), *assumed]}
    return DiagnosisResult(str(summary.get("cause", "")), summary, d.series)


def diagnose_mesh(record: str | Path, *, holdout_start_s: float | None = None,
                  progress: bool | Callable[[str], None] = False) -> GeoDiagnosis:
    """Which part of a mesh model is wrong, from a contract-v3 record.

    The record's TOML names the mesh scenario it is checked against (``[model] scenario
    = "spindle_unit.toml"``, ``docs/measured-data.md``, version 3); its displacement
    channels ``d_<sensor>_um`` and thermometers ``T_<sensor>_C`` are fitted together on a
    parametric reduced model of that scenario, and up to two causes on the scenario's
    own groups are named when established on the hold-out (``arfem diagnose`` on such a
    record, without its files; see ``docs/geometry.md``).

    Parameters
    ----------
    record : str or path-like
        The record's TOML file (``[model]``, ``[dataset]``, ``[columns]``) or its CSV.
    holdout_start_s : float, optional
        Start of the hold-out [s] (default: the last third of the record, moved back to
        the last change of the input before it).
    progress : bool or callable
        True: show the step under way on stderr; a callable is called with each step's
        name instead.

    Returns
    -------
    GeoDiagnosis
        ``verdict``, ``established`` (the causes, each with its parameters and 95 %
        interval), ``holdout_rmse`` per channel [µm, K], ``text`` (the verdict in words).

    Raises
    ------
    InputError
        The record or its scenario is malformed, names a sensor or group the scenario
        lacks, or its hold-out start lies outside it; the message names the file and key.

    Examples
    --------
    Not run as a doctest (the shipped unit's run and diagnosis take about a minute of
    CPU); ``tests/test_mesh_run_folder.py`` runs the same on a coarse unit.

    >>> import subprocess
    >>> _ = subprocess.run(["arfem", "run", "scenarios/spindle_unit.toml",
    ...                     "--out", "run"])                     # doctest: +SKIP
    >>> d = diagnose_mesh("run/record.toml")                     # doctest: +SKIP
    >>> d.established                  # the FEM's own record  # doctest: +SKIP
    ()
    """
    from arfem.models.geodiagnosis.engine import diagnose_geometry
    from arfem.scenarios.geodiagnose import load_mesh_record
    if not callable(progress):
        from arfem.scenarios.progress import Progress
        with Progress(8, "arfem.diagnose_mesh", enabled=bool(progress), tty=True) as bar:
            return diagnose_mesh(record, holdout_start_s=holdout_start_s, progress=bar)
    rec, model, _plant, _sc, _tm = load_mesh_record(record, progress)
    if holdout_start_s is not None and not rec.time_s[0] < holdout_start_s < rec.time_s[-1]:
        raise InputError(f"{holdout_start_s:g} s is outside the record "
                         f"({rec.time_s[0]:g}-{rec.time_s[-1]:g} s)", "holdout_start_s")
    return diagnose_geometry(model, rec, holdout_start_s, progress)


def _dataset_of(data, rod: Rod | None, initial: str | None, name: str) -> tuple:
    """The loaded dataset of :func:`diagnose`'s ``data`` and the warnings of what was
    assumed: a :class:`Record` or TOML path keeps its own ``initial`` (a contradicting
    ``initial`` is refused); samples are read in memory, ``"equilibrium"`` assumed and
    said where ``initial`` is not given."""
    from arfem.scenarios.dataset import dataset_from_columns, load_dataset
    if isinstance(data, (str, Path, Record)):
        if rod is not None:
            raise InputError("give the rod in the dataset TOML's [rod] table, not here", "rod")
        if isinstance(data, Record):
            ds = data._dataset
        else:
            from arfem.scenarios.dataset import read_record_doc
            from arfem.scenarios.georecord import refuse_mesh_channels
            doc = read_record_doc(data)                # the TOML, read once
            if doc.is_mesh:
                raise InputError("names a mesh scenario ([model]): a contract-v3 record is "
                                 "diagnosed by arfem.diagnose_mesh(path), not by the rod's "
                                 "diagnosis",
                                 str(data))
            ds = load_dataset(doc)
            refuse_mesh_channels(ds)
        recorded = "equilibrium" if ds.initial_known else "unknown"
        _initial_of(initial, recorded, str(ds.source))
        return ds, []
    assumed = []
    if initial is None:
        initial = "equilibrium"
        assumed.append('initial = "equilibrium" was assumed (the record starts at '
                       'equilibrium with the ambient); pass initial="unknown" if it did not')
    return dataset_from_columns(data, name=name, rod=rod, initial=initial), assumed


def read_model(path: str | Path) -> StateSpaceModel:
    """Read and validate a compensator's model file (``model.json`` and its kin).

    ``arfem run`` writes ``model.json`` (the paper's AR(1) of the scenario);
    ``arfem diagnose`` writes ``model.json`` (the baseline), ``model_extended.json`` (the
    baseline extended by the named cause) and ``model_mlr.json`` (the thermometer
    regression) where they apply. ``arfem compensate`` replays any of them.

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
