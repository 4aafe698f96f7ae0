"""The first line ``arfem diagnose`` prints, for every plant (issue 41 item 6): written
from the one typed result, :class:`arfem.models.diagnosis.result.Diagnosis`, as
``diagnosis.json`` is (:mod:`arfem.scenarios.diagnosis.document`).

One line for the rod and a mesh. What it shows of the hold-out follows from the result,
not from the plant's name: where the verdict scores the error of one channel as it is
(:attr:`~arfem.models.diagnosis.result.Holdout.gain_whitened_pct` None and one channel,
the rod's growth), the line gives that channel's RMSE before → after, the hold-out's
window and its rows; where it scores errors whitened by each channel's fitted noise (a
mesh), it gives the raw gain and the whitened one the verdict uses.
"""
from __future__ import annotations

from arfem.models.diagnosis.result import unit_shown

__all__ = ["diagnosis_terminal_line"]


def diagnosis_terminal_line(d) -> str:
    """The command's first line of a diagnosis ``d``
    (:class:`~arfem.models.diagnosis.result.Diagnosis`, either engine): the verdict, the
    cause only where it is established (else the best candidate, with the alternatives
    that fit as well, marked as not established), and the hold-out's scores.

    Parameters
    ----------
    d : Diagnosis
        The typed result of :func:`arfem.models.diagnosis.engine.diagnose` (rod) or
        :func:`arfem.models.geodiagnosis.engine.diagnose_geometry` (mesh).

    Returns
    -------
    str
        ``<dataset>: verdict = <verdict>; cause = <cause>[ (best candidate <c>, not
        established)]; hold-out …``.
    """
    named = " + ".join(c.name for c in d.established) or "none"
    line = f"{d.dataset}: verdict = {d.verdict}; cause = {named}"
    if d.verdict != "established" and d.subject is not None:
        best = d.subject + "".join(f" or {a}" for a in d.alternatives)
        line += f" (best candidate {best}, not established)"
    return line + "; " + _holdout_text(d)


def _holdout_text(d) -> str:
    """The hold-out's part of the line (see the module's docstring)."""
    h = d.holdout
    if h.gain_whitened_pct is None and len(h.channels) == 1:
        c = h.channels[0]
        ext = ("extended model" if d.verdict == "established" else
               "best candidate's extended model" if d.causes else
               "no extended model: the baseline")
        unit = unit_shown(c.unit)
        text = (f"hold-out (from {h.start_s / 3600:.2f} h, {h.n_samples} rows) RMSE "
                f"{c.baseline_rmse:.3g} -> {c.extended_rmse:.3g} {unit} ({ext}, gain "
                f"{h.gain_pct:.1f} %)")
    else:
        text = f"hold-out gain {h.gain_pct:.1f} %"
        if h.gain_whitened_pct is not None:
            text += f" (whitened {h.gain_whitened_pct:.1f} %, the one the verdict uses)"
    unseen = _speeds_not_seen_rpm(d)
    sel = (d.evidence.document.get("selection") or {}) if unseen else {}
    if sel.get("speed_engine") == "pipeline":   # the plant's law or eqs. 20-21 predicts them
        how = "are mapped by eqs. 20-21 from the plant's per-speed gains" \
            if sel.get("speed_plant_heat") == "per_speed" else "follow the plant's law (n/n_max)^p"
        text += (f"; speeds not seen before the hold-out ({', '.join(f'{v:g}' for v in unseen)}"
                 f" rpm) {how}; its paper AR(1) reference maps them by eqs. 20-21")
    elif unseen:
        text += (f"; the baseline maps speeds not seen before the hold-out "
                 f"({', '.join(f'{v:g}' for v in unseen)} rpm) by eqs. 20-21, model.json "
                 "inter- or extrapolates their C2 linearly, so arfem compensate scores it "
                 "differently")
    return text


def _speeds_not_seen_rpm(d) -> tuple:
    """The speeds of the hold-out not seen before it [rpm]: a speed-only record on the
    rod (its evidence's ``holdout.speeds_not_seen_before_rpm``); () for any other."""
    if d.plant != "rod_speed":
        return ()
    return tuple(d.evidence.document["holdout"].get("speeds_not_seen_before_rpm") or ())
