"""Fixed-precision numbers for committed reports, and ``arfem reproduce --check``.

``arfem reproduce`` writes ``reports/paper/`` so that running it again, here or on
another machine with the same package versions, leaves ``git diff`` clean:

* the computation runs with one BLAS thread (threadpoolctl), so its round-off does not
  depend on the number of cores (2 threads instead of 1 moved the FEM growth by
  1.1e-11 µm, enough to change the 10th digit of 1 % of the numbers);
* numbers are written with a fixed number of decimals, chosen from the physics, far above
  the round-off and at or below what the models resolve:

  =============================  ==========================  ==============================
  what                           written with                why
  =============================  ==========================  ==============================
  timeseries.csv growths and     5 decimals in µm (10 pm)    the FEM's own mesh error is
  differences [µm]                                           ~1e-5 µm (Richardson); see below
  summary.json µm, %, hours      6 decimals                  a dozen numbers per file
  C1, C2 (AR coefficients),      9 decimals                  C1 fitted vs corrected agree
  Biot number, rel. diffs                                    to 7e-8; shown, not hidden
  time_s, q_W_m2 / time_h        3 / 6 decimals              exact multiples of Δτ / inputs
  =============================  ==========================  ==============================

  Rounding cannot make every machine print the same digits: a number that sits on a
  rounding edge flips its last digit when the round-off differs. Emulating other CPUs'
  BLAS kernels (OPENBLAS_CORETYPE=Nehalem, Prescott, Sandybridge) moves the FEM growth by
  at most 4e-11 µm (mean 1.4e-11), so the expected number of flipped digits among the
  17 000 FEM-derived numbers of the two timeseries.csv files is 0.2 at 6 decimals (one
  was seen) and 0.02 at 5, the precision used;
* wall times and host facts are printed, never written into committed files;
* a regenerated picture that matches the committed one within one grey level in every
  pixel and channel (:func:`same_picture`) keeps the committed bytes: another FreeType
  or libpng, or another CPU's rounding of an anti-aliased edge, moves a few pixels by
  one level, which no reader can see, and the clone stays clean. The comparison is on
  the decoded pixels, not on the bytes (a PNG's compressed bytes change with any
  pixel); a picture of another size, or one pixel off by two levels or more, is a real
  change and is written.

:func:`compare_summary` and :func:`compare_timeseries` (used by
:func:`arfem.scenarios.rod.outputs.check_reproduction`) compare recomputed numbers with committed ones
within :data:`TOLERANCE_UNITS` units in the last written decimal (plus 1e-9 relative):
a real change of the physics or numerics moves them by far more, a machine's round-off by
far less.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

__all__ = ["blas_threads", "CSV_DECIMALS", "WALL_KEYS", "json_decimals", "fixed_metrics", "csv_formats",
           "fixed_columns",
           "compare_summary", "compare_timeseries", "TOLERANCE_UNITS",
           "same_picture", "PICTURE_GREY_LEVELS"]

def blas_threads(n: int = 1):
    """Hold the BLAS/OpenMP thread count of this process at ``n`` (threadpoolctl; a
    context manager whose limit applies at once, so it may also be kept for a worker's
    life; the previous counts come back on exit).

    One thread: the round-off no longer depends on the machine's core count, and the
    small dense eigenproblems here (a few hundred dofs) do not slow down 10-100x when
    threads contend with other jobs on a busy machine. SciPy's own OpenBLAS (used by
    ``eigh``) is loaded first so that the limit reaches it too.
    """
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_limits
    return threadpool_limits(limits=n)


#: Keys holding wall times: printed by the commands, kept out of committed files.
WALL_KEYS = ("fem_wall_s", "wall_s")

#: Decimals of each timeseries.csv column (default: :data:`CSV_UM_DECIMALS`, the µm columns).
CSV_DECIMALS = {"time_s": 3, "q_W_m2": 3, "time_h": 6}
CSV_UM_DECIMALS = 5

#: A recomputed number may differ from the committed one by this many units in the last
#: written decimal (rounding of a number that sits on a rounding edge moves it by one).
TOLERANCE_UNITS = 2


def json_decimals(key: str) -> int:
    """Decimals a summary.json number is written with (see the module's table).

    >>> json_decimals("C1_fitted"), json_decimals("corrected_C2_um"), json_decimals("rmse_um")
    (9, 9, 6)
    """
    if "C1" in key or "C2" in key or key in ("biot", "reciprocity_rel_diff"):
        return 9
    return 6


def _round(v, decimals: int):
    if isinstance(v, bool) or not isinstance(v, (float, np.floating)):
        return v
    v = float(v)
    if not math.isfinite(v):
        return v
    r = round(v, decimals)
    return 0.0 if r == 0 else r            # no "-0.0"


def fixed_metrics(metrics: dict) -> dict:
    """``metrics`` without wall times, every float rounded to :func:`json_decimals`.

    >>> fixed_metrics({"C1": 0.99090288866, "fem_peak_um": 22.1666365884, "wall_s": 3.2,
    ...                "C2_um_by_q_W_m2": {"2000": 0.198482429176}})
    {'C1': 0.990902889, 'fem_peak_um': 22.166637, 'C2_um_by_q_W_m2': {'2000': 0.198482429}}
    """
    out = {}
    for k, v in metrics.items():
        if k in WALL_KEYS:
            continue
        d = json_decimals(k)
        out[k] = ({kk: _round(vv, d) for kk, vv in v.items()} if isinstance(v, dict)
                  else _round(v, d))
    return out


def csv_formats(names) -> list[str]:
    """printf formats of the timeseries.csv columns ``names``."""
    return [f"%.{CSV_DECIMALS.get(n, CSV_UM_DECIMALS)}f" for n in names]


def fixed_columns(columns: dict) -> dict:
    """Each column rounded to its decimals, with no negative zero (a difference that is
    round-off around 0 must not print as "-0.00000" on one machine, "0.00000" on another).

    >>> fixed_columns({"ar_minus_fem_um": np.array([-4e-12, 1.23456789])})
    {'ar_minus_fem_um': array([0.     , 1.23457])}
    """
    return {n: np.round(np.asarray(v, float), CSV_DECIMALS.get(n, CSV_UM_DECIMALS)) + 0.0
            for n, v in columns.items()}


def _tol(decimals: int, ref: float) -> float:
    return TOLERANCE_UNITS * 10.0 ** -decimals + 1e-9 * abs(ref)


def compare_summary(rel: str, committed_path: Path, expected: dict) -> list[str]:
    """Drift lines for one summary.json: missing/extra keys, changed strings and counts,
    numbers beyond tolerance (naming the key, both values and the size of the drift)."""
    try:
        got = json.loads(Path(committed_path).read_text("utf-8"))
    except (OSError, ValueError) as e:
        return [f"{rel}: cannot be read ({e})"]
    drifts = []

    def walk(key, exp, have):
        if isinstance(exp, dict):
            if not isinstance(have, dict):
                drifts.append(f"{rel}: {key}: committed {have!r}, recomputed a table")
                return
            for k in sorted(set(exp) | set(have)):
                walk(f"{key}.{k}", exp.get(k, _MISSING), have.get(k, _MISSING))
            return
        if exp is _MISSING:
            drifts.append(f"{rel}: {key}: committed but no longer computed")
        elif have is _MISSING:
            drifts.append(f"{rel}: {key}: computed ({exp!r}) but not in the committed file")
        elif isinstance(exp, float) and isinstance(have, (int, float)) \
                and not isinstance(have, bool):
            d = json_decimals(key.split(".")[0])
            if not abs(exp - have) <= _tol(d, have):
                drifts.append(f"{rel}: {key}: committed {have!r}, recomputed {exp!r} "
                              f"(drift {exp - have:+.3g}, tolerance {_tol(d, have):.2g})")
        elif exp != have:
            drifts.append(f"{rel}: {key}: committed {have!r}, recomputed {exp!r}")

    for k in sorted(set(expected) | set(got)):
        walk(k, expected.get(k, _MISSING), got.get(k, _MISSING))
    return drifts


_MISSING = object()


def compare_timeseries(rel: str, committed_path: Path, columns: dict) -> list[str]:
    """Drift lines for one timeseries.csv: columns, row count, and per column the largest
    difference beyond tolerance with the time at which it occurs."""
    try:
        text = Path(committed_path).read_text("utf-8")
        header = text.split("\n", 1)[0].strip().split(",")
        data = np.loadtxt(committed_path, delimiter=",", skiprows=1, ndmin=2)
    except (OSError, ValueError) as e:
        return [f"{rel}: cannot be read ({e})"]
    names = list(columns)
    if header != names:
        return [f"{rel}: columns are {header}, recomputed {names}"]
    n = len(next(iter(columns.values())))
    if data.shape != (n, len(names)):
        return [f"{rel}: {data.shape[0]} rows, recomputed {n}"]
    drifts = []
    t = np.asarray(columns["time_s"], float) if "time_s" in columns else np.arange(n)
    for j, name in enumerate(names):
        exp = np.round(np.asarray(columns[name], float), CSV_DECIMALS.get(name, CSV_UM_DECIMALS))
        diff = np.abs(exp - data[:, j])
        tol = TOLERANCE_UNITS * 10.0 ** -CSV_DECIMALS.get(name, CSV_UM_DECIMALS) + 1e-9 * np.abs(data[:, j])
        bad = diff > tol
        dec = CSV_DECIMALS.get(name, CSV_UM_DECIMALS)
        if bad.any():
            i = int(np.argmax(np.where(bad, diff, -1.0)))
            drifts.append(f"{rel}: column {name}: {int(bad.sum())} of {n} rows drift, "
                          f"largest {exp[i] - data[i, j]:+.3g} at time_s = {t[i]:g} "
                          f"(committed {data[i, j]:.{dec}f}, recomputed {exp[i]:.{dec}f}, tolerance "
                          f"{tol[i]:.2g})")
    return drifts


#: Largest difference [grey levels of 255, per channel] between a regenerated picture and
#: the committed one for which the committed bytes are kept (:func:`same_picture`).
PICTURE_GREY_LEVELS = 1


def _pixels(path: Path) -> np.ndarray | None:
    from PIL import Image
    try:
        with Image.open(path) as im:
            return np.asarray(im.convert("RGBA"), dtype=np.int16)
    except (OSError, ValueError):
        return None


def same_picture(new: Path, old: Path, grey_levels: int = PICTURE_GREY_LEVELS) -> bool:
    """True when the PNGs ``new`` and ``old`` have the same size and no pixel differs
    by more than ``grey_levels`` (of 255) in any channel (red, green, blue, alpha).

    Examples
    --------
    >>> import tempfile
    >>> from PIL import Image
    >>> a = np.full((4, 4, 3), 200, np.uint8)
    >>> b = a.copy(); b[1, 2, 0] = 201
    >>> c = a.copy(); c[1, 2, 0] = 202
    >>> with tempfile.TemporaryDirectory() as d:
    ...     for n, x in zip("abc", (a, b, c)):
    ...         Image.fromarray(x).save(f"{d}/{n}.png")
    ...     print(same_picture(Path(d, "b.png"), Path(d, "a.png")),
    ...           same_picture(Path(d, "c.png"), Path(d, "a.png")))
    True False
    """
    a, b = _pixels(Path(new)), _pixels(Path(old))
    if a is None or b is None or a.shape != b.shape:
        return False
    return int(np.abs(a - b).max(initial=0)) <= grey_levels
