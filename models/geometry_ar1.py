"""The AR(1) thermal-error model for any geometry (issue 32 item 4): the paper's lumped
formula generalised from a mesh, and the slowest-mode AR(1) of the reduced model.

Both predict each sensor as a sum of first-order autoregressions, one per input
(a heat source's power or flux, a convection group's h·θ_amb), sampled every Δτ::

    y_n   = Σ_j y_{j,n}                                   (superposition: linear)
    y_j,n = C1_n y_j,n-1 + C2_j,n                         (paper eq. 12)
    C1_n  = exp(−β_n Δτ)                                  (paper eq. 13)
    C2_j,n = K_j(h_n) u_j,n (1 − C1_n)                    (paper eq. 14 generalised)

with u_j,n the input on the step ((n−1)Δτ, nΔτ], β_n the decay rate [1/s] and K_j the
static gain of the sensor for input j [sensor unit per input unit], both at the step's
convection coefficients h_n (they follow the spindle speed when h = a + b·n^m; for a
constant h they are constants, as in the paper). The two models differ in β and K:

* **lumped** (:func:`lumped_rate_1_s`, :func:`lumped_gain`): the whole body at one
  temperature θ̄, C θ̄' = Σ_j P_j u_j − H(h) θ̄ with C = Σ_i ρ_i c_i V_i [J/K] over the
  materials and H = Σ_g h_g A_g [W/K] over the convection groups, so

      β = H / C = h̄ A / (ρcV)        (h̄ the area-weighted mean h, A = Σ A_g)
      K_j = P_j · g_unif / H

  where P_j is the heat into the body per unit of input j [W] and g_unif the sensor's
  output for a uniform rise of 1 K (for a displacement sensor the thermal expansion
  under the body's support: α·L for a freely held bar of length L read at its far end).
  For the paper's rod (lateral h, flux q on an end face of area πR², far end
  adiabatic): β = h·2πRL/(ρc·πR²L) = 2h/(ρcR), and K·q = q·πR²·αL/(h·2πRL) = qαR/(2h)
  = qαa/(λb), paper eqs. 13-14 exactly (:func:`arfem.models.ar1.c2_paper`). It is the
  Galerkin projection of the FEM on the uniform field θ = θ̄·1, exact in the steady
  state only for a body that warms uniformly (Biot number hL/λ ≪ 1 and the heat
  spread before it leaves); a local source (a bearing) on a large body breaks that.
* **slowest-mode** (:func:`modal_ar1`): β = μ₁(h), the slowest eigenvalue of the
  reduced model (A(h)φ = μMφ), and K_j the FEM's exact static gain GᵀA(h)⁻¹F_j.
  It is right in the steady state and in the final decay; it misses the faster modes'
  share of the transient (the rod's corrected AR, :func:`arfem.models.ar1.corrected_coefficients`,
  is this model for the paper's rod, where the slowest mode carries all but O(Bi²)).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from arfem.params import InputError

__all__ = ["lumped_rate_1_s", "lumped_gain", "lumped_ar1", "modal_ar1", "GeometryAR1",
           "ar1_superposed", "step_inputs"]


def _positive(x, name: str) -> float:
    v = float(x)
    if not (math.isfinite(v) and v > 0):
        raise InputError(f"must be > 0, got {x!r}", name)
    return v


def lumped_rate_1_s(heat_capacity_J_K: float, areas_m2, h_W_m2K) -> np.ndarray:
    """Decay rate β = Σ_g h_g A_g / Σ_i ρ_i c_i V_i [1/s] of the lumped body (eq. 13's b).

    Parameters
    ----------
    heat_capacity_J_K : float
        Σ ρ_i c_i V_i over the materials [J/K].
    areas_m2 : array_like, shape (G,)
        Area of each convection group [m²].
    h_W_m2K : array_like, shape (G,) or (n, G)
        Convection coefficient of each group [W/(m²·K)] (per step: rows).

    Returns
    -------
    ndarray, shape () or (n,)
        β [1/s].

    Examples
    --------
    The paper's rod (R = 0.1 m, L = 0.8 m, ρc = 7850·460, h = 55 on the lateral
    surface): β = 2h/(ρcR), C1 = e^{−βΔτ} at Δτ = 30 s (paper eq. 13):

    >>> R, L = 0.1, 0.8
    >>> b = lumped_rate_1_s(7850 * 460 * math.pi * R**2 * L, [2 * math.pi * R * L], [55.0])
    >>> round(float(b) * 7850 * 460 * R / (2 * 55.0), 12), round(math.exp(-float(b) * 30), 4)
    (1.0, 0.9909)
    """
    C = _positive(heat_capacity_J_K, "heat_capacity_J_K")
    A = np.asarray(areas_m2, float)
    h = np.asarray(h_W_m2K, float)
    return (h @ A) / C


def lumped_gain(heat_capacity_J_K: float, areas_m2, h_W_m2K, input_power_W,
                uniform_gain) -> np.ndarray:
    """Static gains K = g_unif P_j / H of the lumped body [sensor unit per input unit].

    Parameters
    ----------
    heat_capacity_J_K : float
        Σ ρcV [J/K] (only checked here; the steady state does not depend on it).
    areas_m2 : array_like, shape (G,)
        Convection group areas [m²].
    h_W_m2K : array_like, shape (G,) or (n, G)
        Convection coefficients [W/(m²·K)].
    input_power_W : array_like, shape (p,)
        Heat into the body per unit of each input [W per input unit].
    uniform_gain : array_like, shape (r,)
        Each sensor's output per kelvin of uniform rise [m/K, or 1 for a thermometer].

    Returns
    -------
    ndarray, shape (r, p) or (n, r, p)

    Examples
    --------
    The paper's rod read at its far end (g_unif = αL): K·q = qαR/(2h), the steady
    growth of paper eqs. 12-14 (21.818 µm at q = 2000 W/m²):

    >>> R, L, a = 0.1, 0.8, 12e-6
    >>> K = lumped_gain(1.0, [2 * math.pi * R * L], [55.0], [math.pi * R**2], [a * L])
    >>> round(float(K[0, 0]) * 2000 * 1e6, 3)
    21.818
    """
    _positive(heat_capacity_J_K, "heat_capacity_J_K")
    H = np.asarray(h_W_m2K, float) @ np.asarray(areas_m2, float)
    if np.any(~(H > 0)):
        raise InputError("the body has no convective loss (Σ h·A = 0): the lumped model "
                         "has no steady state", "convection")
    P = np.asarray(input_power_W, float)
    g = np.asarray(uniform_gain, float)
    return np.multiply.outer(1.0 / H, np.outer(g, P)) if H.ndim else np.outer(g, P) / H


@dataclass(frozen=True)
class GeometryAR1:
    """Coefficients of the superposed AR(1) on a sampled cycle (one row per step).

    Attributes
    ----------
    model : str
        ``"lumped"`` or ``"slowest-mode"``.
    dtau_s : float
        AR step Δτ [s].
    rate_1_s : ndarray, shape (n,)
        β on each step [1/s]; C1 = exp(−βΔτ) (paper eq. 13).
    gain : ndarray, shape (n, r, p)
        Static gain of sensor i for input j on each step [sensor unit per input unit].
    """

    model: str
    dtau_s: float
    rate_1_s: np.ndarray
    gain: np.ndarray

    @property
    def c1(self) -> np.ndarray:
        """C1 on each step [-], paper eq. 13."""
        return np.exp(-self.rate_1_s * self.dtau_s)

    def c2(self, u: np.ndarray) -> np.ndarray:
        """C2 of every (step, sensor, input) [sensor unit], paper eq. 14 generalised:
        K_ij(h_n) u_j,n (1 − C1_n); ``u`` shape (n, p)."""
        return self.gain * np.asarray(u, float)[:, None, :] * (1.0 - self.c1)[:, None, None]

    def simulate(self, u: np.ndarray) -> np.ndarray:
        """Each sensor's response to each input, from rest: shape (n + 1, r, p)."""
        return ar1_superposed(self.c1, self.c2(u))


def lumped_ar1(dtau_s: float, heat_capacity_J_K: float, areas_m2, h_steps_W_m2K,
               input_power_W, uniform_gain) -> GeometryAR1:
    """The lumped AR(1) (module docstring) on steps with convection ``h_steps_W_m2K``
    (shape (n, G)); other parameters as :func:`lumped_gain`."""
    d = _positive(dtau_s, "dtau_s")
    h = np.atleast_2d(np.asarray(h_steps_W_m2K, float))
    return GeometryAR1("lumped", d, lumped_rate_1_s(heat_capacity_J_K, areas_m2, h),
                       lumped_gain(heat_capacity_J_K, areas_m2, h, input_power_W,
                                   uniform_gain))


def modal_ar1(dtau_s: float, slowest_rate_1_s, static_gain) -> GeometryAR1:
    """The slowest-mode AR(1) from the reduced model, per step.

    Parameters
    ----------
    dtau_s : float
        AR step Δτ [s].
    slowest_rate_1_s : array_like, shape (n,)
        μ₁ of A(h_n)φ = μMφ on each step [1/s].
    static_gain : array_like, shape (n, r, p)
        GᵀA(h_n)⁻¹F on each step [sensor unit per input unit].

    Examples
    --------
    A first-order body (μ₁ = 1e-4 1/s, gain 2 per unit input) stepped by u = 1 reaches
    1 − e^{−μ₁t} of its gain:

    >>> ar = modal_ar1(600.0, np.full(10, 1e-4), np.full((10, 1, 1), 2.0))
    >>> y = ar.simulate(np.ones((10, 1)))[:, 0, 0]
    >>> bool(np.allclose(y, 2.0 * (1 - np.exp(-1e-4 * 600.0 * np.arange(11)))))
    True
    """
    d = _positive(dtau_s, "dtau_s")
    mu = np.asarray(slowest_rate_1_s, float)
    if np.any(~(mu > 0)):
        raise InputError("the slowest decay rate must be > 0 (a body without convective "
                         "loss has no steady state)", "slowest_rate_1_s")
    return GeometryAR1("slowest-mode", d, mu, np.asarray(static_gain, float))


def ar1_superposed(c1, c2) -> np.ndarray:
    """Run y_n = C1_n y_n-1 + C2_n from y_0 = 0 for every (sensor, input) pair.

    Parameters
    ----------
    c1 : array_like, shape (n,)
        C1 per step [-].
    c2 : array_like, shape (n, ...)
        C2 per step and pair [sensor unit].

    Returns
    -------
    ndarray, shape (n + 1, ...)
        y_0 = 0, y_1 … y_n; summing over the last axis (inputs) superposes the sources.

    Examples
    --------
    >>> ar1_superposed([0.5, 0.5], [[1.0], [1.0]])[:, 0].tolist()
    [0.0, 1.0, 1.5]
    """
    c1 = np.asarray(c1, float)
    c2 = np.asarray(c2, float)
    y = np.zeros((c1.size + 1,) + c2.shape[1:])
    for n in range(c1.size):
        y[n + 1] = c1[n] * y[n] + c2[n]
    return y


def step_inputs(edges_s, values, dtau_s: float, n_steps: int) -> np.ndarray:
    """Piecewise-constant values (on segments ``edges_s``) on the AR steps: the value
    at each step's midpoint ((n − ½)Δτ), exact when the breakpoints fall on the steps.

    Parameters
    ----------
    edges_s : array_like, shape (m + 1,)
        Segment boundaries [s].
    values : array_like, shape (m, ...)
        Value on each segment.
    dtau_s : float
        AR step [s].
    n_steps : int

    Examples
    --------
    >>> step_inputs([0, 60, 120], [1.0, 2.0], 30.0, 4).tolist()
    [1.0, 1.0, 2.0, 2.0]
    """
    e = np.asarray(edges_s, float)
    v = np.asarray(values, float)
    mid = (np.arange(n_steps) + 0.5) * _positive(dtau_s, "dtau_s")
    return v[np.clip(np.searchsorted(e, mid, side="right") - 1, 0, len(v) - 1)]
