"""The printed model of Zhou et al. (2020), equation by equation (``formula = "paper_literal"``).

Variables (the paper's x_1 … x_24, Sec. 4): for each unit j the six numbers
(Δx_j, Δy_j, Δz_j, Δα_j, Δβ_j, Δγ_j), each in (0, 0.005). The paper gives them all one
bound and compares the rotation sum with ΔE in mm, so the literal model treats them as
plain numbers: translations read as mm, rotations as the same numbers (we carry them
in the scenario's rotation unit, mrad; the pitch and the unit accuracy below do not
depend on the rotation unit at all, only the constraint does).

* eq. 5: the X-, Y-, Z-screw error matrices of a pair, whose translation entry is the
  product Δx·Δα (resp. Δy·Δβ, Δz·Δγ), not Δx;
* eq. 6: their product to first order, :func:`pair_matrix`;
* eq. 7: the chain matrix is the product of the pair matrices, :func:`chain_matrix`;
  eq. 8 and the Sec. 4 worked example keep its first-order part:
  t_x = Σ_j Δx_j·Δα_j, t_y = Σ_j Δy_j·Δβ_j, t_z = Σ_j Δz_j·Δγ_j,
  t_α = Σ_j Δα_j, t_β = Σ_j Δβ_j, t_γ = Σ_j Δγ_j (:func:`chain_terms`);
* eq. 12 / eq. 16 f_1 as in the worked example: f_1 = (t_x + t_y + t_z) / |t_ω|
  = Σ_j ω_j·v_j / |Σ_j ω_j| — a length [mm] (:func:`objectives`);
* eq. 12 for one unit (the worked example's cost exponent): the unit's accuracy
  h_j = ω_j·v_j / |ω_j| [mm] (:func:`unit_accuracy`). Units 2-4 of the printed cost
  carry the factor 1/1.6 and the square root; unit 1's exponent is printed without
  both, which we read as a typesetting slip and treat like the others;
* eq. 14: cost Σ_j a·exp(−h_j / b), a = 1.2, b = 1.6 (x in mm);
* eq. 13, 15, 16: the constraint m_E = |t_ω| = sqrt(t_α² + t_β² + t_γ²) <= ΔE.

The model needs no geometry: lever arms do not appear (this is its weakness, see
``reports/allocation/README.md``), which is why it can be run exactly as printed.
"""
from __future__ import annotations

import numpy as np

__all__ = ["pair_matrix", "chain_matrix", "chain_terms", "unit_accuracy", "objectives"]


def _split(X):
    """(n, n_units, 6) [Δx, Δy, Δz, Δα, Δβ, Δγ] -> v (n, u, 3), ω (n, u, 3)."""
    X = np.asarray(X, float)
    X = X.reshape(X.shape[0], -1, 6) if X.ndim == 2 else X
    return X[..., :3], X[..., 3:]


def pair_matrix(x) -> np.ndarray:
    """Error matrix of one pair, eq. 6 (first order), for x = (Δx, Δy, Δz, Δα, Δβ, Δγ).

    Parameters
    ----------
    x : array_like, shape (6,)
        The paper's six variables of one unit (translations [mm], rotations as numbers).

    Returns
    -------
    ndarray, shape (4, 4)
        [[1, −Δγ, Δβ, Δx·Δα], [Δγ, 1, −Δα, Δy·Δβ], [−Δβ, Δα, 1, Δz·Δγ], [0, 0, 0, 1]].

    Examples
    --------
    >>> pair_matrix([2, 3, 4, 0.5, 0.25, 0.1])[:3, 3].tolist()
    [1.0, 0.75, 0.4]
    """
    dx, dy, dz, da, db, dg = np.asarray(x, float)
    return np.array([[1.0, -dg, db, dx * da], [dg, 1.0, -da, dy * db],
                     [-db, da, 1.0, dz * dg], [0.0, 0.0, 0.0, 1.0]])


def chain_matrix(xs) -> np.ndarray:
    """Chain error matrix E = g_01 g_12 … (eq. 7), the full product (no truncation).

    Parameters
    ----------
    xs : array_like, shape (n_units, 6)

    Returns
    -------
    ndarray, shape (4, 4)

    Examples
    --------
    >>> E = chain_matrix([[1e-3] * 6, [2e-3] * 6])
    >>> round(float(E[0, 3]), 12)      # t_x = 1e-6 + 4e-6, plus higher-order products
    5e-06
    """
    E = np.eye(4)
    for x in np.asarray(xs, float):
        E = E @ pair_matrix(x)
    return E


def chain_terms(X) -> dict:
    """First-order terms of the chain matrix (eq. 8, Sec. 4): t_x … t_γ per candidate.

    Parameters
    ----------
    X : array_like, shape (n, 6·n_units)
        Candidates, unit after unit, each (Δx, Δy, Δz, Δα, Δβ, Δγ).

    Returns
    -------
    dict
        ``t_v`` (n, 3) = (t_x, t_y, t_z) = Σ_j (Δx_j Δα_j, Δy_j Δβ_j, Δz_j Δγ_j);
        ``t_w`` (n, 3) = (t_α, t_β, t_γ) = Σ_j ω_j.

    Examples
    --------
    >>> t = chain_terms([[1, 0, 0, 2, 0, 0, 3, 0, 0, 4, 0, 0]])
    >>> t["t_v"].tolist(), t["t_w"].tolist()
    ([[14.0, 0.0, 0.0]], [[6.0, 0.0, 0.0]])
    """
    v, w = _split(np.atleast_2d(X))
    return {"t_v": np.sum(v * w, axis=1), "t_w": np.sum(w, axis=1)}


def unit_accuracy(X) -> np.ndarray:
    """h_j = ω_j·v_j / |ω_j| of every unit (eq. 12 applied to one unit) [mm].

    Examples
    --------
    >>> round(float(unit_accuracy([[3e-3, 0, 0, 1e-3, 0, 0]])[0, 0]), 9)
    0.003
    """
    v, w = _split(np.atleast_2d(X))
    nw = np.linalg.norm(w, axis=2)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(nw > 0, np.sum(v * w, axis=2) / np.where(nw > 0, nw, 1.0), 0.0)


def objectives(X, a: float = 1.2, b_mm: float = 1.6) -> dict:
    """f_1 [mm], f_2 (cost, eq. 14), m_E = |t_ω| (eq. 13) and h_j of each candidate.

    Parameters
    ----------
    X : array_like, shape (n, 6·n_units)
    a, b_mm : float
        Cost constants of eq. 14 (paper: 1.2 and 1.6 mm).

    Returns
    -------
    dict
        ``f1_mm`` (n,), ``cost`` (n,), ``m_E`` (n,), ``h_mm`` (n, n_units).

    Examples
    --------
    >>> o = objectives([[1e-3, 0, 0, 1e-3, 0, 0, 2e-3, 0, 0, 1e-3, 0, 0]])
    >>> round(float(o["f1_mm"][0]), 9), round(float(o["m_E"][0]), 9)
    (0.0015, 0.002)
    """
    t = chain_terms(X)
    mE = np.linalg.norm(t["t_w"], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        f1 = np.where(mE > 0, t["t_v"].sum(axis=1) / np.where(mE > 0, mE, 1.0), 0.0)
    h = unit_accuracy(X)
    return {"f1_mm": f1, "cost": np.sum(a * np.exp(-h / b_mm), axis=1), "m_E": mE, "h_mm": h}
