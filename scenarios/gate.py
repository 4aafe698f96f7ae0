"""``arfem check``'s gate, whatever the plant: the verdict of one scenario (its
criteria, each a measured value against its limit), its line on the terminal and the
reports CI reads (JUnit XML, JSON). The rod's check (:mod:`arfem.scenarios.rod.checking`)
and the mesh's (:mod:`arfem.scenarios.geometry.check`) both give a
:class:`ScenarioResult`; this module needs neither.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

from arfem.params import InputError

__all__ = ["Skipped", "Criterion", "ScenarioResult", "result_line", "junit_xml",
           "json_report", "check_report_path"]


@dataclass(frozen=True)
class Skipped:
    path: str
    reason: str


@dataclass(frozen=True)
class Criterion:
    """One criterion of one scenario: measured ``value`` against ``limit`` (same unit)."""

    name: str            # "max_abs_diff_pct_of_peak" | "C1_abs_diff"
    value: float
    limit: float
    unit: str
    passed: bool
    message: str


@dataclass
class ScenarioResult:
    scenario: str
    file: str
    model: str
    criteria: list = field(default_factory=list)
    wall_s: float = 0.0
    biot: float = float("nan")          # hR/λ of the FEM's rod: the paper AR's validity
    notes: tuple = ()                   # reported, not gated (mesh scenarios: the other AR)

    @property
    def passed(self) -> bool:
        return all(c.passed for c in self.criteria)


def result_line(r: ScenarioResult) -> str:
    head = "PASS" if r.passed else "FAIL"
    parts = "; ".join(("" if c.passed else "FAILED ") + c.message for c in r.criteria)
    bi = f", Bi = {r.biot:.3f}" if r.biot == r.biot else ""
    notes = "".join(f"; {n}" for n in r.notes)
    return f"{head} {r.scenario} ({r.file}, {r.model} AR{bi}): {parts}{notes}"


# -- reports ---------------------------------------------------------------------------------

def junit_xml(results, skipped, wall_s: float = 0.0) -> bytes:
    """JUnit XML: one ``testsuite`` "arfem check" with a ``testcase`` per scenario and
    criterion (``classname`` = the scenario, ``name`` = the criterion); a failed one holds
    a ``failure`` whose ``message`` gives the figure and the limit. Skipped files are
    ``skipped`` test cases, so every file the gate saw is listed."""
    n_fail = sum(not c.passed for r in results for c in r.criteria)
    n_tests = sum(len(r.criteria) for r in results) + len(skipped)
    attrs = {"tests": str(n_tests), "failures": str(n_fail), "errors": "0",
             "skipped": str(len(skipped)), "time": f"{wall_s:.3f}"}
    root = ET.Element("testsuites", {"name": "arfem check", **attrs})
    suite = ET.SubElement(root, "testsuite", {"name": "arfem check", **attrs})
    for r in results:
        per = r.wall_s / max(len(r.criteria), 1)
        for c in r.criteria:
            tc = ET.SubElement(suite, "testcase", {
                "classname": f"arfem.check.{r.scenario}", "name": f"{c.name} ({r.model} AR)",
                "file": r.file, "time": f"{per:.3f}"})
            if not c.passed:
                f = ET.SubElement(tc, "failure", {"message": c.message,
                                                  "type": "ARDoesNotTrackFEM"})
                f.text = (f"scenario {r.scenario} ({r.file}): {c.name} = {c.value:.6g} "
                          f"[{c.unit}] exceeds the limit {c.limit:.6g}")
            else:
                ET.SubElement(tc, "system-out").text = "\n".join((c.message,) + r.notes)
    for s in skipped:
        tc = ET.SubElement(suite, "testcase", {"classname": "arfem.check.skipped",
                                               "name": s.path, "time": "0"})
        ET.SubElement(tc, "skipped", {"message": s.reason})
    ET.indent(root)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True) + b"\n"


def json_report(results, skipped) -> dict:
    """The same as :func:`junit_xml`, as data."""
    return {
        "generator": "arfem check",
        "passed": sum(r.passed for r in results),
        "failed": sum(not r.passed for r in results),
        "scenarios": [{"scenario": r.scenario, "file": r.file, "model": r.model,
                       "biot": r.biot if r.biot == r.biot else None, "passed": r.passed,
                       "notes": list(r.notes),
                       "criteria": [{"name": c.name, "value": c.value, "limit": c.limit,
                                     "unit": c.unit, "passed": c.passed,
                                     "message": c.message} for c in r.criteria]}
                      for r in results],
        "skipped": [{"file": s.path, "reason": s.reason} for s in skipped],
    }


def check_report_path(path, flag: str) -> Path:
    """Refuse, before any work, a report path that cannot be written as a file."""
    from arfem.scenarios.outdir import check_out_path
    p = Path(path)
    if p.is_dir():
        raise InputError("is a directory; give a file name", f"{flag} {p}")
    try:
        check_out_path(p.parent)        # may be created; not a file, writable
    except InputError as e:
        raise InputError(f"cannot be written: {e}", f"{flag} {p}") from None
    return p
