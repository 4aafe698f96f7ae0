"""A measured record as the diagnosis sees it: :class:`Dataset` (validated, immutable
arrays) and the robust flags computed on it (growth outliers, sampling gaps).

Reading a record from its files (``NAME.toml`` + ``NAME.csv``, the measured-data
contract in ``docs/measured-data.md``) is :func:`arfem.scenarios.records.dataset.load_dataset`;
nothing here touches a file.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from arfem.params import InputError, Rod, Schedule

__all__ = ["Dataset", "hampel_outliers", "sampling_gaps", "GAP_FACTOR", "observations"]

#: A sampling interval longer than this multiple of the median interval is a gap.
GAP_FACTOR = 3.0


@dataclass(frozen=True)
class Dataset:
    """One measured record, validated; every array is over the kept rows.

    Attributes
    ----------
    name : str
        ``[dataset] name`` (the TOML stem if absent).
    source : Path
        The TOML file.
    time_s : ndarray
        Sample times [s], strictly increasing, >= 0.
    growth_um : ndarray
        Measured axial growth [µm], finite everywhere.
    q_W_m2 : ndarray or None
        Heat flux [W/m²] over (t_{i-1}, t_i] (zero-order hold; from 0 for the first row).
    speed_rpm : ndarray or None
        Spindle speed [1/min] over (t_{i-1}, t_i].
    ambient_C : ndarray or None
        Measured ambient air temperature [°C], finite (short gaps filled, see ``notes``).
    temperatures : dict of str to ndarray
        Every ``T_<name>_C`` column [°C] (NaN where a cell was empty).
    rod : Rod
        ``[rod]`` values, the seed paper's where not given.
    initial_known : bool
        False when ``[dataset] initial = "unknown"`` (record not started at equilibrium).
    outliers : ndarray of bool
        Growth samples flagged as outliers by :func:`hampel_outliers` (kept, not removed).
    gaps : list of (float, float)
        (start_s, end_s) of sampling intervals longer than 3x the median interval.
    notes : list of str
        What was done to the data and what was noticed, human-readable.
    sensors : dict of str to str
        ``[sensors.<column>] description``.
    csv_path : Path
        The CSV file.
    line_numbers : ndarray of int
        CSV line (1-based, header = line 1) of each kept row.
    extra_columns : dict of str to ndarray
        Columns the contract does not know, carried as text over the kept rows (ignored
        by the models).
    growth_resolution_um : float
        Resolution of the growth sensor [µm] estimated from the record
        (:func:`arfem.models.diagnosis.stats.resolution`), 0 where it is not quantised.
    unobserved : dict of str to ndarray
        Rows with a time and an input but an empty ``growth_um``: their ``time_s`` and
        inputs (``q_W_m2``/``speed_rpm``, ``ambient_C``, ``T_<name>_C``). The observation
        is missing, the input is not: a model runs over these rows too (dropping them
        would hold the next row's input over their interval).
    """

    name: str
    source: Path
    time_s: np.ndarray
    growth_um: np.ndarray
    q_W_m2: np.ndarray | None
    speed_rpm: np.ndarray | None
    ambient_C: np.ndarray | None
    temperatures: dict[str, np.ndarray]
    rod: Rod
    initial_known: bool
    outliers: np.ndarray
    gaps: list[tuple[float, float]]
    notes: list[str]
    sensors: dict[str, str]
    csv_path: Path | None = None
    line_numbers: np.ndarray | None = field(default=None, repr=False)
    extra_columns: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    unobserved: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    growth_resolution_um: float = 0.0

    @property
    def noise_floor_um(self) -> float:
        """Smallest noise σ a rule may assume [µm]: the quantisation noise of the growth
        sensor, resolution/√12 (0 for an unquantised record)."""
        return self.growth_resolution_um / np.sqrt(12.0)

    @property
    def input_kind(self) -> str:
        """``"q_W_m2"`` when the heat flux is recorded (preferred), else ``"speed_rpm"``."""
        return "q_W_m2" if self.q_W_m2 is not None else "speed_rpm"

    @property
    def n_rows(self) -> int:
        return int(self.time_s.size)

    def schedule(self, ambient: bool = False) -> Schedule:
        """The recorded inputs as a piecewise-constant :class:`Schedule` from t = 0.

        Segment i is (t_{i-1}, t_i] with t_{-1} = 0 (a first row at t = 0 adds no
        segment). ``ambient=True`` also carries ``ambient_C`` (each row's value held
        over the interval that ends at it). Only for datasets with ``q_W_m2``.
        """
        if self.q_W_m2 is None:
            raise InputError("has no q_W_m2 column; a schedule needs the heat flux",
                             str(self.source))
        t = np.concatenate([[0.0], self.time_s])
        d = np.diff(t)
        keep = d > 0
        amb = None
        if ambient and self.ambient_C is not None:
            amb = self.ambient_C[keep]
        return Schedule(d[keep], self.q_W_m2[keep], amb)


# -- robust flags -------------------------------------------------------------------

def hampel_outliers(values, half_window: int = 5, n_sigma: float = 6.0,
                    floor: float = 0.0) -> np.ndarray:
    """Hampel-type outlier flags: residual from the median of the neighbours beyond ``n_sigma`` robust σ.

    The reference for each sample is the median of its ``2 * half_window`` neighbours
    (itself excluded); a flagged sample must also differ by the threshold, in the same
    direction, from both nearest unflagged samples (an isolated spike, not the peak or
    kink of a smooth record). σ is 1.4826 × the median absolute deviation of the
    residuals over the whole record (σ for Gaussian noise), so a slow trend does not
    inflate it; ``floor`` is a lower bound on σ in the unit of ``values`` (e.g. the
    quantisation step).

    Parameters
    ----------
    values : array_like
        Samples, e.g. growth [µm], finite.
    half_window : int
        Neighbours on each side used for the reference median [-].
    n_sigma : float
        Threshold in robust standard deviations [-].
    floor : float
        Smallest σ used, in the unit of ``values``.

    Returns
    -------
    ndarray of bool

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> x = 10 * np.sin(np.linspace(0, 3, 500)) + rng.normal(0, 0.1, 500)
    >>> x[[50, 300]] += [3.0, -2.0]
    >>> np.flatnonzero(hampel_outliers(x)).tolist()
    [50, 300]
    """
    x = np.asarray(values, dtype=float)
    k = int(half_window)
    if x.size < 2 * k + 1 or k < 1:
        return np.zeros(x.shape, dtype=bool)
    # median of the 2k neighbours, the sample itself excluded: on a smooth record this
    # is ~ the sample's value (residual = noise + curvature), and a spike cannot mask itself
    pad = np.pad(x, k, mode="reflect", reflect_type="odd")   # keeps a linear trend
    win = np.lib.stride_tricks.sliding_window_view(pad, 2 * k + 1)
    neigh = np.delete(win, k, axis=1)
    r = x - np.median(neigh, axis=1)
    sigma = max(1.4826 * float(np.median(np.abs(r - np.median(r)))), float(floor))
    if sigma == 0.0:
        return np.zeros(x.shape, dtype=bool)
    thr = n_sigma * sigma
    cand = np.abs(r) > thr
    if not cand.any():
        return cand
    # a spike also stands out by the threshold from BOTH nearest unflagged samples, in the
    # same direction; the peak or kink of a smooth record (the growth rate jumps where the
    # heat input switches) does not, so it is not flagged
    idx = np.arange(x.size)
    ok = np.where(~cand, idx, -1)
    prev = np.concatenate([[-1], np.maximum.accumulate(ok)[:-1]])
    ok = np.where(~cand, idx, x.size)
    nxt = np.concatenate([np.minimum.accumulate(ok[::-1])[::-1][1:], [x.size]])
    out = np.zeros(x.size, dtype=bool)
    for i in np.flatnonzero(cand):
        sides = [x[i] - x[j] for j in (prev[i], nxt[i]) if 0 <= j < x.size]
        out[i] = bool(sides) and all(np.sign(d) == np.sign(r[i]) and abs(d) > thr
                                     for d in sides)
    return out


def sampling_gaps(time_s, factor: float = GAP_FACTOR) -> list[tuple[float, float]]:
    """Intervals whose length exceeds ``factor`` × the median sampling interval.

    Parameters
    ----------
    time_s : array_like
        Strictly increasing sample times [s].
    factor : float
        Multiple of the median interval beyond which an interval is a gap [-].

    Returns
    -------
    list of (start_s, end_s)

    Examples
    --------
    >>> sampling_gaps([0, 30, 60, 90, 400, 430])
    [(90.0, 400.0)]
    """
    t = np.asarray(time_s, dtype=float)
    if t.size < 3:
        return []
    d = np.diff(t)
    med = float(np.median(d))
    idx = np.flatnonzero(d > factor * med)
    return [(float(t[i]), float(t[i + 1])) for i in idx]


def observations(ds):
    """Time [s], growth [µm] (NaN where not observed), the observed and outlier masks and
    the inputs (a dict by column, None where not recorded) over every row the record has
    an input for: rows with an empty ``growth_um`` keep their input (dropping it would
    merge its interval into the next one's) -- see ``Dataset.unobserved``. Speed-only
    records use the observed rows only. The rod plant reads the same rows
    (:func:`arfem.models.diagnosis.rod_plant.rod_plant`)."""
    t = np.asarray(ds.time_s, float)
    y = np.asarray(ds.growth_um, float)
    un = getattr(ds, "unobserved", None)
    cols = {"q_W_m2": ds.q_W_m2, "speed_rpm": ds.speed_rpm, "ambient_C": ds.ambient_C,
            **ds.temperatures}
    cols = {k: None if v is None else np.asarray(v, float) for k, v in cols.items()}
    outl = np.asarray(ds.outliers, bool)
    if ds.input_kind != "q_W_m2" or not un or not np.size(un.get("time_s", [])):
        return t, y, np.ones(t.size, bool), outl, cols
    tu = np.asarray(un["time_s"], float)
    order = np.argsort(np.concatenate([t, tu]), kind="stable")
    t2 = np.concatenate([t, tu])[order]
    obs = np.concatenate([np.ones(t.size, bool), np.zeros(tu.size, bool)])[order]
    y2 = np.concatenate([y, np.full(tu.size, np.nan)])[order]
    out2 = np.concatenate([outl, np.zeros(tu.size, bool)])[order]
    if np.any(np.diff(t2) <= 0):         # an unobserved row repeats a time: leave them out
        return t, y, np.ones(t.size, bool), outl, cols
    cols2 = {}
    for k, v in cols.items():
        if v is None:
            cols2[k] = None
            continue
        w = un.get(k)
        w = np.full(tu.size, np.nan) if w is None else np.asarray(w, float)
        v2 = np.concatenate([v, w])[order]
        if k == "ambient_C" and np.isnan(v2).any():      # an ambient is needed on every interval
            ok = np.isfinite(v2)
            v2 = np.interp(t2, t2[ok], v2[ok])
        cols2[k] = v2
    return t2, y2, obs, out2, cols2
