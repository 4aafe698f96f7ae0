"""``diagnosis.json`` written from the one typed result (issue 41, stage 3): the
:class:`arfem.models.diagnosis.result.Diagnosis` of either engine becomes the document of
``docs/commands/diagnose.md`` here, at the edge, and nowhere else.

Contract v2 (the rod: a ``q_W_m2`` or ``speed_rpm`` record) and contract v3 (a mesh
record) keep their keys; both carry the verdict's keys (``verdict``, ``cause``,
``causes``, ``parameters``, ``parameters_ci95``, ``best_candidate``, ``holdout``).
"""
from __future__ import annotations

from collections.abc import Mapping

__all__ = ["document", "mesh_document", "plain"]


def plain(v):
    """``v`` with every frozen mapping made a plain dict and every tuple a list, order
    kept: the document ``json`` writes, which a caller may change.

    >>> from arfem.models.diagnosis.result import frozen_mapping
    >>> plain(frozen_mapping({"a": {"b": [{"c": 1}]}}))
    {'a': {'b': [{'c': 1}]}}
    """
    if isinstance(v, Mapping):
        return {k: plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    return v


def document(d, rom_statement: dict | None = None) -> dict:
    """diagnosis.json's content of a diagnosis ``d`` of either engine: contract v2 for
    the rod (its evidence's document, as the engine laid it out), contract v3 for a
    mesh (:func:`mesh_document`; ``rom_statement`` the reduced model's error statement,
    ``{}`` where it was not made)."""
    if d.plant == "mesh":
        return mesh_document(d, rom_statement or {})
    return plain(d.evidence.document)


def _mesh_entries(d) -> list:
    """``causes`` of a v3 document: each named cause, its kind, target, name, parameters
    and 95 % intervals."""
    return [{"cause": c.cause, "target": c.target, "name": c.name,
             "parameters": dict(c.parameters), "ci95": {k: list(v) for k, v in c.ci95.items()}}
            for c in d.causes]


def mesh_document(d, rom_statement: dict) -> dict:
    """diagnosis.json's content of a mesh diagnosis ``d`` (contract v3 keys; the rod's
    verdict keys); ``rom_statement`` the reduced model against the full solve."""
    est = d.verdict == "established"
    ent = _mesh_entries(d)
    h = d.holdout
    s = {"contract_version": 3, "dataset": d.dataset, "model": "mesh", "verdict": d.verdict,
         "verdict_text": d.text,
         "cause": ent[0]["name"] if est else "none", "causes": ent if est else [],
         "parameters": ent[0]["parameters"] if est else {},
         "parameters_ci95": ent[0]["ci95"] if est else {},
         "holdout": {"start_s": h.start_s, "gain_pct": h.gain_pct,
                     "gain_whitened_pct": h.gain_whitened_pct,
                     "per_channel": {c.column: {"baseline_rmse": c.baseline_rmse,
                                                "extended_rmse": c.extended_rmse,
                                                "mlr_rmse": c.mlr_rmse}
                                     for c in h.channels},
                     "how_chosen": h.how_chosen},
         "noise_sigma": {c.column: c.noise_sigma for c in d.channels},
         "nominal_ljung_box_p_neff": {c.column: c.whiteness_p for c in d.channels},
         "ranking": [{"cause": r.cause, "bic": r.bic, "f_test_p": r.f_test_p,
                      "holdout_whitened_rms": r.holdout_whitened_rms,
                      "not_named_alone_because": r.refused}
                     for r in d.evidence.ranking],
         "below_resolution": d.below_resolution,
         "best_candidate_beaten_by_mlr": d.beaten_by_regression,
         "not_searched": list(d.not_searched),
         "reduced_model": rom_statement}
    s["alternatives"] = list(d.alternatives)
    if not est and d.causes:
        s["best_candidate"] = {"cause": d.subject + "".join(f" or {a}" for a in d.alternatives),
                               "causes": ent, "named_by_selection_rules": True,
                               "not_established_because": list(d.failed)}
    return s
