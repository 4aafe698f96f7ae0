"""Acceptance checks comparing the AR(1) model with the FEM.

:func:`check_ar_tracks_fem` is the CI criterion of issue 3 ("AR tracks FEM"):
the paper's AR(1) growth must follow the FEM growth on the paper's duty cycle
within a fraction of the FEM peak, and the C1 fitted to the FEM series must
agree with the closed form of paper eq. 13. It returns failure messages rather
than raising, so a scenario runner can collect and report them.
"""
from __future__ import annotations


import numpy as np

from arfem.params import InputError, check_finite

__all__ = ["check_ar_tracks_fem", "MAX_DEV_OF_PEAK", "C1_TOL"]

#: Largest allowed max|AR − FEM| as a fraction of the FEM peak growth [-]. The
#: paper AR(1) misses the 3D rod by 2.57 % of the peak at the paper's h
#: (Bi = 0.11): the 1D fin theory's error is O(Bi), and the corrected AR removes it.
MAX_DEV_OF_PEAK = 0.03

#: Largest allowed |C1_fitted − C1_closed| [-] at Δτ = 30 s. Measured 2.44e-4 for
#: the paper rod (its slowest 3D mode decays at 0.973 b, not b). dC1/dh =
#: −C1 2Δτ/(ρcR) ≈ −1.6e-4 per W/(m²·K), so 5e-4 flags an h wrong by ≳ 3 W/(m²·K)
#: beyond the model's own bias (h = 80 instead of 55 gives 4.4e-3).
C1_TOL = 5e-4


def check_ar_tracks_fem(fem_growth, ar_growth, c1_fitted: float, c1_closed: float,
                        max_dev_of_peak: float = MAX_DEV_OF_PEAK,
                        c1_tol: float = C1_TOL) -> list[str]:
    """Failures of the "AR(1) tracks FEM" criterion; an empty list means it passes.

    Parameters
    ----------
    fem_growth : array_like
        FEM growth ΔL at the AR sample times [any length unit, e.g. m].
    ar_growth : array_like
        AR(1) growth at the same times, same unit.
    c1_fitted : float
        C1 fitted to the FEM series (:func:`arfem.models.ar1.fit_ar1`) [-].
    c1_closed : float
        C1 of the AR being checked, e.g. paper eq. 13 [-].
    max_dev_of_peak : float
        Allowed max|AR − FEM| / max|FEM| [-].
    c1_tol : float
        Allowed |c1_fitted − c1_closed| [-].

    Returns
    -------
    list of str
        One line per failed criterion, with the measured value and the limit.

    Examples
    --------
    >>> fem = np.array([0.0, 1.0, 2.0, 1.5])
    >>> check_ar_tracks_fem(fem, fem * 1.01, 0.9910, 0.9909)
    []
    >>> check_ar_tracks_fem(fem, fem * 1.05, 0.9910, 0.9860)    # doctest: +NORMALIZE_WHITESPACE
    ['max|AR - FEM| = 5.000 % of the FEM peak, limit 3.000 %',
     '|C1_fitted - C1_closed| = 5.000e-03, limit 5.0e-04']
    """
    fem = _series("fem_growth", fem_growth)
    ar = _series("ar_growth", ar_growth)
    if fem.shape != ar.shape:
        raise InputError(f"has {ar.size} samples, FEM has {fem.size}", "ar_growth")
    peak = float(np.max(np.abs(fem)))
    if not peak > 0:
        raise InputError("FEM growth is identically zero; nothing to compare", "fem_growth")
    c1f = _scalar("c1_fitted", c1_fitted)
    c1c = _scalar("c1_closed", c1_closed)
    failures = []
    dev = float(np.max(np.abs(ar - fem))) / peak
    if not dev <= max_dev_of_peak:
        failures.append(f"max|AR - FEM| = {100 * dev:.3f} % of the FEM peak, "
                        f"limit {100 * max_dev_of_peak:.3f} %")
    dc1 = abs(c1f - c1c)
    if not dc1 <= c1_tol:
        failures.append(f"|C1_fitted - C1_closed| = {dc1:.3e}, limit {c1_tol:.1e}")
    return failures


def _series(name: str, values) -> np.ndarray:
    try:
        a = np.asarray(values, float)
    except (TypeError, ValueError):
        raise InputError("must be numbers", name) from None
    if a.ndim != 1 or a.size == 0:
        raise InputError(f"must be a non-empty 1D series, got shape {a.shape}", name)
    if not np.all(np.isfinite(a)):
        raise InputError("must be finite", name)
    return a


_scalar = check_finite
