"""``arfem report DIR`` writes only where arfem wrote, never over a user's file, lists its
page with its current hash, and never makes a folder unresumable (issue 29).

Properties verified (each set-up is one the reliability test of issue 29 found):

* a user's own ``report.html`` is never replaced -- in a folder arfem never wrote to, in an
  arfem folder whose ``.arfem-outputs.json`` was deleted, and in one whose manifest no
  longer lists ``report.html`` -- exit 2, one line, the file's bytes unchanged;
* where it writes, the manifest lists ``report.html`` with the SHA-256 of the file now on
  disk (not the old one);
* a sweep killed before it wrote its outputs, then ``arfem report``, then the same sweep
  again: the resume runs to the end and replaces the page (the case of issue 29, item 4);
* an arfem ``report.html`` the user edited is kept unless ``--force``;
* a folder a running command holds (a sweep's lock) is refused, not written under it.
"""
from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import pytest

from arfem.scenarios.cli import main
from arfem.scenarios.outdir import OWNERSHIP_MANIFEST, adopt_outputs, lock_out_dir

USER = b"<html><body>my own notes</body></html>\n"


def _sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def _manifest(d: Path) -> dict:
    return json.loads((d / OWNERSHIP_MANIFEST).read_text("utf-8"))["files"]


def _report(d: Path, capsys, *flags) -> tuple[int, list[str]]:
    capsys.readouterr()
    rc = main(["report", str(d), *flags])
    return rc, [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]


def _arfem_folder(d: Path) -> Path:
    d.mkdir()
    (d / "summary.json").write_text('{"rmse_um": 0.25}', "utf-8")
    adopt_outputs(d, ["summary.json"])
    return d


def _refused_unchanged(d: Path, capsys, what: str):
    rc, err = _report(d, capsys)
    assert rc == 2 and len(err) == 1 and err[0].startswith("arfem: error:"), err
    assert what in err[0], err
    assert (d / "report.html").read_bytes() == USER


def test_a_folder_arfem_never_wrote_to_is_refused(tmp_path, capsys):
    d = tmp_path / "mine"
    d.mkdir()
    (d / "summary.json").write_text('{"a": 1}', "utf-8")
    (d / "report.html").write_bytes(USER)
    _refused_unchanged(d, capsys, "arfem did not write this folder")
    (d / "report.html").unlink()                       # and without a page: nothing written
    rc, err = _report(d, capsys)
    assert rc == 2 and not (d / "report.html").exists()


def test_an_arfem_folder_whose_manifest_was_deleted_is_refused(tmp_path, capsys):
    d = _arfem_folder(tmp_path / "o")
    (d / OWNERSHIP_MANIFEST).unlink()
    (d / "report.html").write_bytes(USER)
    _refused_unchanged(d, capsys, "arfem did not write this folder")


def test_a_report_the_manifest_no_longer_lists_is_refused(tmp_path, capsys):
    d = _arfem_folder(tmp_path / "o")
    assert _report(d, capsys)[0] == 0
    man = json.loads((d / OWNERSHIP_MANIFEST).read_text("utf-8"))
    del man["files"]["report.html"]
    (d / OWNERSHIP_MANIFEST).write_text(json.dumps(man), "utf-8")
    (d / "report.html").write_bytes(USER)
    _refused_unchanged(d, capsys, "report.html was not written by arfem")
    _refused_unchanged(d, capsys, "report.html was not written by arfem")  # --force or not
    assert main(["report", str(d), "--force"]) == 2
    assert (d / "report.html").read_bytes() == USER


def test_the_manifest_lists_the_page_with_its_current_hash(tmp_path, capsys):
    """Written twice over a changed folder: each time the manifest holds the hash of the
    file on disk (before issue 29 it kept the old one)."""
    d = _arfem_folder(tmp_path / "o")
    assert _report(d, capsys)[0] == 0
    assert _manifest(d)["report.html"] == _sha(d / "report.html")
    first = _sha(d / "report.html")
    (d / "extra.json").write_text('{"b_um": 2.0}', "utf-8")
    adopt_outputs(d, ["extra.json"])
    assert _report(d, capsys)[0] == 0
    assert _sha(d / "report.html") != first
    assert _manifest(d)["report.html"] == _sha(d / "report.html")
    assert _manifest(d)["summary.json"] == _sha(d / "summary.json")   # others kept


def test_an_edited_arfem_page_needs_force(tmp_path, capsys):
    d = _arfem_folder(tmp_path / "o")
    assert _report(d, capsys)[0] == 0
    (d / "report.html").write_bytes(USER)
    _refused_unchanged(d, capsys, "changed since arfem wrote it")
    rc, _ = _report(d, capsys, "--force")
    assert rc == 0 and (d / "report.html").read_bytes() != USER
    assert _manifest(d)["report.html"] == _sha(d / "report.html")


def test_a_folder_a_running_command_holds_is_refused(tmp_path, capsys):
    """A sweep holds its folder's lock for its whole run; the report does not wait for it
    or write under it."""
    d = _arfem_folder(tmp_path / "o")
    with lock_out_dir(d, wait=False):
        rc, err = _report(d, capsys)
    assert rc == 2 and len(err) == 1 and "another arfem command" in err[0]
    assert not (d / "report.html").exists()


def test_missing_folder_and_file_are_one_line(tmp_path, capsys):
    (tmp_path / "f").write_text("x")
    for target in (tmp_path / "nope", tmp_path / "f"):
        rc, err = _report(target, capsys)
        assert rc == 2 and len(err) == 1 and "not a directory" in err[0]
    assert not (tmp_path / "nope").exists()


def test_a_killed_sweep_resumes_after_report(tmp_path, capsys):
    """Issue 29, item 4: a sweep killed after storing some points (no outputs written
    yet), ``arfem report`` on it, then the same sweep: it resumes to the end (exit 0),
    replaces the page, and the manifest lists the new page's hash."""
    from unittest import mock

    from sweep_fakes import fake_point, flaky_point, write_small_sweep

    from arfem.scenarios.sweep import load_sweep, run_sweep
    sweep = load_sweep(write_small_sweep(tmp_path))
    out = tmp_path / "o"
    # the kill: the outputs' switch never happens (the process dies in write_outputs)
    with mock.patch("arfem.scenarios.sweep.runner.write_outputs",
                    side_effect=KeyboardInterrupt):
        with pytest.raises(KeyboardInterrupt):
            run_sweep(sweep, out, workers=1, progress=False, point_fn=flaky_point)
    assert (out / "points").is_dir() and not (out / "README.md").exists()
    rc, err = _report(out, capsys)
    assert rc == 0, err                          # the store is arfem's: sweep.json listed
    assert _manifest(out)["report.html"] == _sha(out / "report.html")
    before = _sha(out / "report.html")
    with mock.patch("arfem.scenarios.sweep.report.write_figures", lambda *a: []):
        rep = run_sweep(sweep, out, workers=1, progress=False, point_fn=fake_point)
    assert rep.n_computed == 1 and rep.n_stored_before == 2       # h = 55 failed before
    assert (out / "README.md").is_file() and _sha(out / "report.html") != before
    assert _manifest(out)["report.html"] == _sha(out / "report.html")
    shutil.rmtree(out)
