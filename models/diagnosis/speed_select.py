"""The selection rules of speed-only records (their one home; the orchestration is
:mod:`arfem.models.diagnosis.engine`): forward-chaining validation folds
(:func:`forward_folds`), the validation RMSE (:func:`cv_rmse`), the frame structure
chosen by it (:func:`select_frame_structure`), the post hoc median block ratio of
``--frame-search average`` (:func:`median_block_ratio`) and of ``--drift-last``
(:func:`drift_last`).
"""
from __future__ import annotations

import numpy as np

from arfem.models.diagnosis.speed_frame import (FrameEnsemble, temperature_matrix,
                                                fit_frame_thermometers, frame_structures)

__all__ = ["forward_folds", "cv_rmse", "select_frame_structure", "median_block_ratio",
           "drift_last", "INPUT_FREE_CAUSES"]


def forward_folds(t, speed, rows, min_train_frac: float = 0.25, max_folds: int = 4):
    """Forward-chaining validation blocks inside the fit window (``rows``).

    Each block starts at a speed step (so it usually opens with a speed the training
    part has not seen -- the situation of the hold-out) once at least ``min_train_frac``
    of the fit window lies before it, and ends at the next start or at the end of the
    fit window. Without such steps: the last half of the fit window in three blocks.

    Parameters
    ----------
    t : array_like
        Sample times [s].
    speed : array_like
        Spindle speed on each row [1/min].
    rows : ndarray of bool
        Fit window.
    min_train_frac : float
        Least fraction of the fit window's time span before the first block [-].
    max_folds : int
        Most blocks kept (the last ones).

    Returns
    -------
    list of (ndarray of bool, ndarray of bool)
        (train rows, validation rows) per block; training rows precede the block.

    Examples
    --------
    >>> t = np.arange(1, 1201) * 60.0            # 20 h
    >>> sp = np.where((t // 14400) % 2 == 0, 1000.0, 0.0)
    >>> f = forward_folds(t, sp, np.ones(t.size, bool))
    >>> [(round(t[v][0] / 3600), round(t[v][-1] / 3600)) for _, v in f]
    [(8, 12), (12, 16), (16, 20)]
    """
    t = np.asarray(t, float)
    speed = np.asarray(speed, float)
    tf = t[rows]
    t0, t1 = float(tf[0]), float(tf[-1])
    steps = t[np.flatnonzero(np.diff(speed) != 0) + 1]
    starts = [s for s in steps if t0 + min_train_frac * (t1 - t0) <= s < t1 - 0.05 * (t1 - t0)]
    if len(starts) < 2:
        starts = list(t0 + (t1 - t0) * np.array([0.5, 2 / 3, 5 / 6]))
    starts = starts[-max_folds:]
    ends = starts[1:] + [np.inf]
    return [(rows & (t < a), rows & (t >= a) & (t < b)) for a, b in zip(starts, ends)]


def median_block_ratio(per, base_per) -> float:
    """Median over the validation blocks of a candidate's RMSE over the baseline's [-].

    The naming test of ``frame_search="average"`` (post hoc): a cause is named if this is
    <= 1 − MIN_GAIN, i.e. it cuts the baseline's error by >= MIN_GAIN on the typical
    block. The pooled RMSE and the block count it replaces were each decided by one
    block: the pooled RMSE by the worst (one badly extrapolated speed outweighs three
    blocks cut by half), and "wins a majority" by whichever block sits at the margin
    (2 of 4 blocks with a 48 % pooled cut was ``none``).

    Examples
    --------
    >>> median_block_ratio([1.0, 1.0, 6.0, 0.5], [2.0, 2.0, 3.0, 2.5])
    0.5
    """
    r = [a / b for a, b in zip(per, base_per) if b > 0]
    return float(np.median(r)) if r else float("nan")


#: speed-only causes whose prediction is driven by no recorded input: a trend in time
INPUT_FREE_CAUSES = ("sensor_drift",)


def drift_last(named, tests) -> list:
    """Order of the candidate causes with the input-free ones (:data:`INPUT_FREE_CAUSES`,
    a linear drift in time) put behind every input-driven cause that passes its naming
    test (``tests[c]["significant"]``); otherwise ``named`` unchanged.

    The rule of ``drift_last=True`` (post hoc, after the rolling-origin evaluation of the
    real record). On a fit window in which the machine mostly warms up, a linear drift
    in time and a slow thermal response (a frame that follows the thermometers) both
    fit the slow rise, and validation blocks inside that window cannot tell them apart.
    They part only after the window: the thermal response follows the recorded
    temperatures when the machine cools, the drift goes on rising. So where an
    explanation from the recorded inputs passes the test, the drift is not preferred to
    it on a validation score; it is named only when no input-driven cause passes.

    Parameters
    ----------
    named : sequence of str
        Candidate causes, best first (``"none"`` excluded).
    tests : dict
        Cause -> its naming test, with the bool ``"significant"``.

    Returns
    -------
    list of str

    Examples
    --------
    >>> t = {"sensor_drift": {"significant": True}, "frame_expansion": {"significant": True},
    ...      "ambient_drift": {"significant": False}}
    >>> drift_last(["sensor_drift", "ambient_drift", "frame_expansion"], t)
    ['ambient_drift', 'frame_expansion', 'sensor_drift']
    >>> t["frame_expansion"]["significant"] = False
    >>> drift_last(["sensor_drift", "ambient_drift", "frame_expansion"], t)
    ['sensor_drift', 'ambient_drift', 'frame_expansion']
    """
    named = list(named)
    if not any(c not in INPUT_FREE_CAUSES and tests[c]["significant"] for c in named):
        return named
    return ([c for c in named if c not in INPUT_FREE_CAUSES]
            + [c for c in named if c in INPUT_FREE_CAUSES])


def cv_rmse(fitter, y, folds) -> tuple[float, list[float]]:
    """Forward-chaining validation RMSE [µm]: pooled over the blocks, and per block.

    ``fitter(train_rows) -> prediction over the record`` (or None: not applicable).
    """
    errs, per = [], []
    for tr, va in folds:
        p = fitter(tr)
        if p is None:
            return float("nan"), []
        r = (y - p)[va]
        errs.append(r)
        per.append(float(np.sqrt(np.mean(r * r))))
    e = np.concatenate(errs) if errs else np.zeros(0)
    return (float(np.sqrt(np.mean(e * e))) if e.size else float("nan")), per


def select_frame_structure(t, y, speed, temperatures, rows, folds, fold_maps,
                           search: str = "narrow"):
    """The frame structure with the least forward-chaining validation RMSE.

    ``fold_maps[i] = (seen, W)``: the speed mapping rebuilt from fold i's training rows
    (used by the per-speed-gain structures). Every structure of
    :func:`frame_structures` (``search``) is scored on the same blocks; a tie keeps the
    structure earlier in that list.

    Parameters
    ----------
    t : array_like
        Sample times [s].
    y : array_like
        Measured growth [µm].
    speed : array_like
        Spindle speed on each row [1/min].
    temperatures : dict
        Sensor name -> temperature series [°C].
    rows : ndarray of bool
        Fit window (before the hold-out, not outliers); the scoring uses ``folds`` only.
    folds : list of (ndarray of bool, ndarray of bool)
        (train, validation) rows, as from :func:`forward_folds`.
    fold_maps : list of (seen, W)
        Speed mapping per fold, as from :func:`speed_to_heat_map` on its training rows.
    search : {"narrow", "wide", "average"}
        Which structures to compare (:data:`FRAME_SEARCHES`); "average" compares none
        and returns the :class:`FrameEnsemble` of the "narrow" structures with an empty
        table (its validation RMSE is the ``frame_expansion`` candidate's own).

    Returns
    -------
    structure : FrameStructure or None
        The best structure; None if none could be scored.
    table : dict
        Structure label -> pooled validation RMSE [µm] (nan if not applicable).
    """
    names, _ = temperature_matrix(temperatures)
    if search == "average":
        # no choice to make: the candidate's own validation (by the caller) scores it
        members = tuple(frame_structures(len(names), "average"))
        return (FrameEnsemble(members) if members else None), {}
    table, best = {}, None
    for st in frame_structures(len(names), search):
        it = iter(fold_maps)

        def fitter(tr, st=st, it=it):
            seen, W = next(it)
            f = fit_frame_thermometers(t, y, speed, tr, seen, W, temperatures, st)
            return None if f is None else f.prediction
        score, _ = cv_rmse(fitter, y, folds)
        table[st.label] = score
        if np.isfinite(score) and (best is None or score < best[0]):
            best = (score, st)
    return (None if best is None else best[1]), table
