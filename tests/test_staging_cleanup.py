"""Staging folders ``.arfem-staging-*`` left by a kill are removed by the next run, inside
``--out`` and beside it, and never look like output (issue 29).

Properties verified:

* a dead staging folder (its lock free: the run that made it was killed) inside ``--out``,
  beside it for this ``--out``, and beside it for ANOTHER ``--out`` of the same parent
  folder, is removed by the next command that checks an ``--out`` there;
* a staging folder whose lock is held (a live run) is left alone;
* a dead staging folder holding another folder's uncommitted switch journal is left for
  that folder's own recovery (it holds that folder's old files), not deleted;
* staging folders are hidden (a leading dot) and neither ``arfem report`` nor the
  non-empty check counts them as output.
"""
from __future__ import annotations

import fcntl
import json
import os
from pathlib import Path

from arfem.scenarios.html_report import write_html_report
from arfem.scenarios.outdir import (_sibling_prefix, adopt_outputs, check_out_path,
                                    prepare_out_dir)


def _stage(parent: Path, name: str, journal: bool = False) -> Path:
    d = parent / name
    (d / "new").mkdir(parents=True)
    (d / "lock").write_text("")
    (d / "new" / "summary.json").write_text('{"half": 1}')
    if journal:
        (d / "journal.json").write_text(json.dumps({"files": [], "dirs": []}))
    return d


def test_dead_staging_inside_and_beside_are_removed_live_ones_kept(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "a.json").write_text("{}")
    adopt_outputs(out, ["a.json"])
    inside = _stage(out, ".arfem-staging-abc12345")
    beside = _stage(tmp_path, _sibling_prefix(out) + "zz11")
    other = _stage(tmp_path, _sibling_prefix(tmp_path / "another") + "yy22")
    live = _stage(tmp_path, _sibling_prefix(tmp_path / "third") + "xx33")
    foreign_switch = _stage(tmp_path, ".arfem-staging-qq99", journal=True)
    fd = os.open(live / "lock", os.O_RDWR)
    fcntl.flock(fd, fcntl.LOCK_EX)                     # a live run holds it
    try:
        check_out_path(out)                            # what every command does first
    finally:
        os.close(fd)
    assert not inside.exists() and not beside.exists() and not other.exists()
    assert live.exists()
    assert foreign_switch.exists()                     # its folder recovers it, not us
    assert (out / "a.json").exists()


def test_a_fresh_out_clears_dead_staging_of_a_killed_fresh_run(tmp_path):
    """A fresh run killed while computing leaves its staging folder beside the (absent)
    --out; the next run into any --out in that folder removes it."""
    dead = _stage(tmp_path, _sibling_prefix(tmp_path / "first") + "aa00")
    check_out_path(tmp_path / "second")
    assert not dead.exists()


def test_staging_folders_never_look_like_output(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    _stage(out, ".arfem-staging-live0001")
    fd = os.open(out / ".arfem-staging-live0001" / "lock", os.O_RDWR)
    fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        prepare_out_dir(out)                           # empty for arfem: no refusal
        (out / "summary.json").write_text('{"x_um": 1.0}')
        page = write_html_report(out).read_text("utf-8")
    finally:
        os.close(fd)
    assert ".arfem-staging" not in page and "half" not in page
    assert all(p.name.startswith(".") for p in out.iterdir()
               if p.name not in ("summary.json", "report.html"))
