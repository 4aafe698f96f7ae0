"""Rolling-origin evaluation: refit before each origin, score the block after it.

One hold-out is one draw: on a thermal record it is a few hours of one speed program, and
which model wins it can turn on that program alone. A rolling-origin evaluation repeats
the out-of-sample test at many origins -- here every speed step after a minimum training
span (:func:`speed_step_origins`) -- fitting each time on everything before the origin and
scoring the block up to the next origin (:func:`rolling_origin`), and reports the
distribution of the hold-out errors and how often a model beats the others
(:func:`summarize`).

Pure: arrays and a callable in, numbers out; nothing here reads or writes a file.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["speed_step_origins", "blocks", "rolling_origin", "summarize", "OriginScore",
           "stability_origins", "verdict_stability", "STABILITY_ORIGINS"]


def speed_step_origins(t, speed, start_s: float = 0.0, min_block_s: float = 0.0):
    """Times at which the speed changes, from ``start_s`` on.

    Parameters
    ----------
    t : array_like
        Sample times [s], increasing.
    speed : array_like
        Spindle speed on each row [1/min].
    start_s : float
        Earliest origin [s] (the least training span).
    min_block_s : float
        Drop an origin whose block -- up to the next origin or the end of the record --
        is shorter than this [s].

    Returns
    -------
    list of float
        Origins [s]: the time of the first row at each new speed.

    Examples
    --------
    >>> t = np.arange(0, 10.0)
    >>> sp = np.array([0, 0, 5, 5, 5, 0, 0, 0, 7, 7])
    >>> speed_step_origins(t, sp)
    [2.0, 5.0, 8.0]
    >>> speed_step_origins(t, sp, start_s=3.0, min_block_s=2.0)
    [5.0]
    """
    t = np.asarray(t, float)
    speed = np.asarray(speed, float)
    steps = t[np.flatnonzero(np.diff(speed) != 0) + 1]
    steps = [float(s) for s in steps if s >= start_s]
    ends = steps[1:] + [float(t[-1])]
    return [s for s, e in zip(steps, ends) if e - s >= min_block_s]


def blocks(t, origins, block_s: float | None = None):
    """Scoring block of each origin: from it to the next origin (or the end of the
    record), cut at ``block_s`` after it if given.

    Parameters
    ----------
    t : array_like
        Sample times [s], increasing.
    origins : sequence of float
        Origins [s], increasing.
    block_s : float, optional
        Longest block [s].

    Returns
    -------
    list of ndarray of bool
        Rows with origin <= t < end, one mask per origin.

    Examples
    --------
    >>> t = np.arange(0, 10.0)
    >>> [np.flatnonzero(b).tolist() for b in blocks(t, [2.0, 5.0], block_s=2.0)]
    [[2, 3], [5, 6]]
    >>> [np.flatnonzero(b).tolist() for b in blocks(t, [2.0, 5.0])]
    [[2, 3, 4], [5, 6, 7, 8, 9]]
    """
    t = np.asarray(t, float)
    origins = [float(o) for o in origins]
    if any(b <= a for a, b in zip(origins, origins[1:])):
        raise ValueError("origins must be strictly increasing")
    out = []
    for i, o in enumerate(origins):
        end = origins[i + 1] if i + 1 < len(origins) else np.inf
        if block_s is not None:
            end = min(end, o + float(block_s))
        m = (t >= o) & (t < end)
        if i + 1 == len(origins) and block_s is None:
            m = t >= o                          # the last block runs to the end
        out.append(m)
    return out


@dataclass
class OriginScore:
    """Hold-out RMSE [µm] of each model on one origin's block."""

    origin_s: float
    block_end_s: float
    n: int
    rmse_um: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)


def rolling_origin(t, y, origins, fit_predict, block_s: float | None = None, valid=None,
                   mapper=map, only=None):
    """Fit before each origin, score the block after it.

    ``fit_predict(n_train, y_train)`` is given only the growth before the origin --
    ``y_train = y[:n_train]``, the rows with t < origin -- and returns
    ``{model name: prediction [µm] over every row of t}``; exogenous inputs (speed,
    temperatures), which are known at prediction time, it takes from its own closure.
    Nothing at or after the origin of the measured ``y`` reaches it. It may also return
    ``(predictions, info)``, ``info`` a dict kept in :attr:`OriginScore.info` (e.g. the
    cause named at that origin).

    Parameters
    ----------
    t : array_like
        Sample times [s], increasing.
    y : array_like
        Measured growth [µm].
    origins : sequence of float
        Origins [s], increasing (e.g. :func:`speed_step_origins`).
    fit_predict : callable
        ``(n_train: int, y_train: ndarray) -> dict[str, ndarray]``.
    block_s : float, optional
        Longest scoring block [s] (:func:`blocks`).
    valid : array_like of bool, optional
        Rows that may be scored (e.g. not flagged as outliers); default all.
    mapper : callable
        ``map``-like, called once as ``mapper(fit_predict, n_trains, y_trains)``; e.g. an
        executor's ``map`` to fit the origins in parallel.
    only : sequence of float, optional
        Evaluate only these of ``origins`` (a cheaper subset), each on the same block
        as in the full evaluation (blocks still end at the next of ``origins``).

    Returns
    -------
    list of OriginScore

    Examples
    --------
    >>> t = np.arange(0, 6.0); y = t.copy()
    >>> last = lambda n, yt: {"persist": np.full(t.size, yt[-1])}
    >>> [(s.origin_s, s.rmse_um["persist"]) for s in rolling_origin(t, y, [3.0, 5.0], last)]
    [(3.0, 1.5811388300841898), (5.0, 1.0)]
    """
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    ok = np.ones(t.size, bool) if valid is None else np.asarray(valid, bool)
    masks = blocks(t, origins, block_s)
    if only is not None:
        keep = [i for i, o in enumerate(origins) if any(np.isclose(o, x) for x in only)]
        origins, masks = [origins[i] for i in keep], [masks[i] for i in keep]
    n_trains = [int(np.searchsorted(t, o, side="left")) for o in origins]   # rows t < origin
    results = list(mapper(fit_predict, n_trains, [y[:n].copy() for n in n_trains]))
    out = []
    for o, m, res in zip(origins, masks, results):
        preds, info = res if isinstance(res, tuple) else (res, {})
        sc = m & ok
        score = OriginScore(float(o), float(t[m][-1]) if m.any() else float(o), int(sc.sum()),
                            info=dict(info))
        for name, p in preds.items():
            r = (y - np.asarray(p, float))[sc]
            score.rmse_um[name] = float(np.sqrt(np.mean(r * r))) if r.size else float("nan")
        out.append(score)
    return out


def summarize(scores, candidate: str, others):
    """Distribution of the hold-out RMSE per model and how often ``candidate`` beats the
    others.

    Parameters
    ----------
    scores : list of OriginScore
    candidate : str
        The model whose wins are counted.
    others : sequence of str
        Models it must beat (strictly lower RMSE).

    Returns
    -------
    dict
        ``n_origins``; per model ``{"median_um", "mean_um", "q25_um", "q75_um", "min_um",
        "max_um"}`` under ``"rmse"``; ``"beats_all"`` (origins where ``candidate`` is
        below every one of ``others``), ``"beats"`` (per other model) and ``"ties"``
        (per other model: equal RMSE, e.g. the candidate *is* that model there).

    Examples
    --------
    >>> s = [OriginScore(0, 1, 5, {"a": 1.0, "b": 2.0}), OriginScore(1, 2, 5, {"a": 3.0, "b": 2.0})]
    >>> d = summarize(s, "a", ["b"])
    >>> d["beats_all"], d["rmse"]["a"]["median_um"]
    (1, 2.0)
    """
    names = list(dict.fromkeys(k for s in scores for k in s.rmse_um))
    out = {"n_origins": len(scores), "rmse": {}}
    for k in names:
        v = np.array([s.rmse_um.get(k, np.nan) for s in scores], float)
        v = v[np.isfinite(v)]
        out["rmse"][k] = ({"median_um": float(np.median(v)), "mean_um": float(v.mean()),
                           "q25_um": float(np.percentile(v, 25)),
                           "q75_um": float(np.percentile(v, 75)),
                           "min_um": float(v.min()), "max_um": float(v.max())}
                          if v.size else None)
    others = list(others)
    c = [s.rmse_um[candidate] for s in scores]
    out["beats"] = {o: int(sum(a < s.rmse_um[o] for a, s in zip(c, scores))) for o in others}
    out["ties"] = {o: int(sum(a == s.rmse_um[o] for a, s in zip(c, scores))) for o in others}
    out["beats_all"] = int(sum(all(a < s.rmse_um[o] for o in others)
                               for a, s in zip(c, scores)))
    return out


#: verdict stability: at most this many rolling origins by default
STABILITY_ORIGINS = 10


def stability_origins(t, u, n_max: int = STABILITY_ORIGINS):
    """Rolling origins for the verdict's stability: every change of the input ``u`` that
    leaves at least 40 % of the record to fit and at least max(1 h, 5 % of the record) to
    score (the default hold-out's own conditions), thinned evenly to at most ``n_max``.

    Parameters
    ----------
    t : array_like
        Sample times [s], increasing.
    u : array_like
        The input on each row (heat flux [W/m²] or speed [1/min]).
    n_max : int
        Most origins returned.

    Returns
    -------
    list of float
        Origins [s].

    Examples
    --------
    >>> t = np.arange(0, 100.0) * 3600
    >>> u = (np.arange(100) // 10) % 2
    >>> [o / 3600 for o in stability_origins(t, u)]
    [40.0, 50.0, 60.0, 70.0, 80.0, 90.0]
    >>> [o / 3600 for o in stability_origins(t, u, 3)]
    [40.0, 60.0, 90.0]
    """
    t = np.asarray(t, float)
    span = float(t[-1] - t[0])
    org = speed_step_origins(t, u, t[0] + 0.4 * span)
    org = [o for o in org if t[-1] - o >= max(3600.0, 0.05 * span)]
    if len(org) > n_max >= 1:
        idx = np.unique(np.round(np.linspace(0, len(org) - 1, n_max)).astype(int))
        org = [org[i] for i in idx]
    return org


def verdict_stability(diagnose_at, origins, subject: str | None, mapper=map) -> dict:
    """How stable a verdict is across hold-out splits: the diagnosis rerun with its
    hold-out starting at each origin (cheap refits: ``diagnose_at`` should skip the
    intervals), counting where the selection rules name ``subject`` and where its
    extended model also beats the baseline on that hold-out.

    Parameters
    ----------
    diagnose_at : callable
        ``origin_s -> summary`` (the diagnosis.json dict of a diagnosis whose hold-out
        starts at ``origin_s``; nothing at or after it is fitted).
    origins : sequence of float
        Hold-out starts [s] (e.g. :func:`stability_origins`).
    subject : str or None
        The cause (or best candidate, "a+b" for a pair) the full diagnosis is about;
        None: count where no cause is named.
    mapper : callable
        ``map``-like, e.g. an executor's.

    Returns
    -------
    dict
        ``n_origins``, ``origins_s``, ``per_origin`` (``origin_s``, ``named`` -- what the
        selection rules named there, "none" if nothing --, ``verdict``,
        ``holdout_gain_pct``), ``named`` (origins naming ``subject``), ``confirmed`` (of
        those, the hold-out gain > 0), ``verdicts`` (count per verdict), ``text``.

    Examples
    --------
    >>> fake = lambda o: {"cause": "x" if o > 1 else "none", "causes": [{"cause": "x"}] if o > 1 else [],
    ...                   "verdict": "established" if o > 1 else "explained",
    ...                   "holdout": {"gain_pct": 5.0 if o > 2 else -1.0}}
    >>> s = verdict_stability(fake, [1.0, 2.0, 3.0], "x")
    >>> s["named"], s["confirmed"], s["text"].split(" (")[0]
    (2, 1, 'x named by the selection rules at 2 of 3 rolling origins')
    """
    origins = [float(o) for o in origins]
    per = []
    for o, s in zip(origins, mapper(diagnose_at, origins)):
        named_list = s.get("causes") or (s.get("best_candidate") or {}).get("causes") or []
        if not named_list and (s.get("best_candidate") or {}).get("named_by_selection_rules"):
            named_list = [{"cause": s["best_candidate"]["cause"]}]
        named = "+".join(c["cause"] for c in named_list) or "none"
        per.append({"origin_s": o, "named": named, "verdict": s.get("verdict"),
                    "holdout_gain_pct": float(s["holdout"]["gain_pct"])})
    n = len(per)
    verdicts = {}
    for p in per:
        verdicts[p["verdict"]] = verdicts.get(p["verdict"], 0) + 1
    span = (f"{origins[0] / 3600:.1f}-{origins[-1] / 3600:.1f} h" if n else "none")
    vtxt = ", ".join(f"{k} {v}" for k, v in sorted(verdicts.items(), key=lambda kv: -kv[1]))
    if subject and subject != "none":
        k = sum(p["named"] == subject for p in per)
        m = sum(p["named"] == subject and p["holdout_gain_pct"] > 0 for p in per)
        txt = (f"{subject} named by the selection rules at {k} of {n} rolling origins "
               f"({span}) and better than the baseline on the hold-out from {m} of them; "
               f"verdicts there (refits without intervals): {vtxt}.")
    else:
        others = {}
        for p in per:
            if p["named"] != "none":
                others[p["named"]] = others.get(p["named"], 0) + 1
        k = sum(p["named"] == "none" for p in per)
        m = k
        txt = (f"no cause named at {k} of {n} rolling origins ({span})"
               + ("; named elsewhere: " + ", ".join(f"{c} at {v}" for c, v in others.items())
                  if others else "") + f"; verdicts there (refits without intervals): {vtxt}.")
    return {"n_origins": n, "origins_s": origins, "per_origin": per, "subject": subject,
            "named": k, "confirmed": m, "verdicts": verdicts, "text": txt if n else
            "no rolling origin: the record has no change of the input in its last 60 %."}
