"""Diagnosis of a user's own mesh model (issue 33): a parametric reduced model of a
:class:`arfem.fem.body.ThermalBody`, causes named on the model's own groups, their
fits with 95 % intervals, and the verdict in the words of the rod's diagnosis
(:mod:`arfem.models.diagnosis.verdict`). Pure: arrays and dataclasses in, results out.
"""
