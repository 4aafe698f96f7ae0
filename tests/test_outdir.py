"""Never lose a user's file: ownership of --out, inputs, the all-or-nothing switch across
a kill at any rename, live staging directories (locks, not PIDs), and one-line errors.

Every "unchanged" below is checked by SHA-256 of every file in the directory.
"""
from __future__ import annotations

import errno
import fcntl
import hashlib
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import arfem.scenarios.outdir as sio
from arfem.params import InputError
from arfem.scenarios.cli import main
from scenario_texts import small_scenario

ROOT = Path(__file__).resolve().parents[1]

SCENARIO = small_scenario()

DATASET_CSV = "time_s,growth_um,q_W_m2\n" + "".join(
    f"{30 * i},{0.01 * i if i < 200 else 0.01 * (400 - i):.4f},{2000 if i < 200 else 0}\n"
    for i in range(400))


def snapshot(d: Path) -> dict:
    """{relative path: sha256} of every file under ``d`` (hidden ones too)."""
    return {p.relative_to(d).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(d.rglob("*")) if p.is_file()}


def stage(out, files: dict, **kw):
    with sio.staged_out_dir(out, **kw) as st:
        for rel, text in files.items():
            (st / rel).parent.mkdir(parents=True, exist_ok=True)
            (st / rel).write_text(text)


def one_line_error(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("arfem: error: ") and "Traceback" not in err
    return err


# -- item 1: --force never replaces an input or a file arfem did not write -------------

def test_diagnose_force_into_the_dataset_folder_keeps_the_data(tmp_path, capsys):
    """The reported case: D/case.toml names series.csv; diagnose --out D --force must
    refuse (series.csv is the user's measured data, and an input), exit 2, one line,
    before the work, and leave every file of D byte for byte."""
    d = tmp_path / "D"
    d.mkdir()
    (d / "series.csv").write_text(DATASET_CSV)
    (d / "case.toml").write_text('[dataset]\nname = "c"\ncsv = "series.csv"\n')
    before = snapshot(d)
    assert main(["diagnose", str(d / "case.toml"), "--out", str(d), "--force"]) == 2
    err = one_line_error(capsys)
    assert "series.csv" in err and "--force or not" in err
    assert snapshot(d) == before


def test_force_never_replaces_a_foreign_file(tmp_path):
    """A README.md that arfem did not write (a clone's) survives --force; the whole set
    is refused before the first rename, so --out is unchanged."""
    out = tmp_path / "clone"
    out.mkdir()
    (out / "README.md").write_text("hand-written")
    (out / "code.py").write_text("x = 1")
    before = snapshot(out)
    with pytest.raises(InputError, match="README.md was not written by arfem"):
        stage(out, {"results.csv": "a", "README.md": "generated"}, force=True)
    assert snapshot(out) == before


def test_force_replaces_arfem_own_files_and_records_them(tmp_path):
    """What --force is for: arfem's own earlier files (even edited since) are replaced,
    the user's other files are not touched, and the manifest lists arfem's files with
    their SHA-256."""
    out = tmp_path / "out"
    stage(out, {"a.txt": "1", "sub/b.txt": "1"})
    (out / "notes.txt").write_text("mine")
    (out / "a.txt").write_text("edited by the user")
    with pytest.raises(InputError, match="a.txt was changed since arfem wrote it"):
        stage(out, {"a.txt": "2"}, update=True)
    stage(out, {"a.txt": "2", "sub/b.txt": "2"}, force=True)
    assert (out / "a.txt").read_text() == "2" and (out / "notes.txt").read_text() == "mine"
    man = json.loads((out / sio.OWNERSHIP_MANIFEST).read_text())["files"]
    assert set(man) == {"a.txt", "sub/b.txt"}
    assert man["a.txt"] == hashlib.sha256(b"2").hexdigest()


def test_an_input_is_never_replaced_even_if_arfem_wrote_it(tmp_path):
    """A file arfem wrote earlier and that this run reads (through arfem.io or named by
    the caller) is an input: refused, --force or not."""
    from arfem.io import read_text_utf8
    out = tmp_path / "out"
    stage(out, {"series.csv": "old", "other.txt": "x"})
    before = snapshot(out)
    with pytest.raises(InputError, match="series.csv is an input of this run"):
        stage(out, {"series.csv": "new"}, force=True, inputs=[out / "series.csv"])
    read_text_utf8(out / "other.txt")                      # read -> an input, for free
    with pytest.raises(InputError, match="other.txt is an input of this run"):
        stage(out, {"other.txt": "new"}, force=True)
    assert snapshot(out) == before


def test_run_force_refuses_a_foreign_output_name_before_the_work(tmp_path, capsys):
    """`arfem run --force` into a folder whose summary.md is the user's: refused by the
    early check (one line, exit 2), nothing changed."""
    (tmp_path / "case.toml").write_text(SCENARIO)
    (tmp_path / "summary.md").write_text("my summary")
    before = snapshot(tmp_path)
    assert main(["run", str(tmp_path / "case.toml"), "--out", str(tmp_path), "--force"]) == 2
    assert "summary.md was not written by arfem" in one_line_error(capsys)
    assert snapshot(tmp_path) == before


def test_run_into_its_own_folder_with_force_twice(tmp_path, capsys):
    """--out . beside the scenario: the first run writes and records its files; the
    second --force run replaces exactly those; the scenario file is never touched."""
    (tmp_path / "case.toml").write_text(SCENARIO)
    sha_case = snapshot(tmp_path)["case.toml"]
    for _ in range(2):
        assert main(["run", str(tmp_path / "case.toml"), "--out", str(tmp_path),
                     "--force"]) == 0
    snap = snapshot(tmp_path)
    assert snap["case.toml"] == sha_case
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".arfem-staging")]
    owned = json.loads((tmp_path / sio.OWNERSHIP_MANIFEST).read_text())["files"]
    assert "case.toml" not in owned and "summary.json" in owned


# -- item 2: the switch is all or nothing, also across a kill at any rename ------------

OLD = {"a.txt": "old a", "b.txt": "old b", "sub/c.txt": "old c"}
NEW = {"a.txt": "new a", "b.txt": "new b", "sub/c.txt": "new c", "d.txt": "new d",
       "sub2/e.txt": "new e"}

KILLER = textwrap.dedent("""
    import os, sys
    import arfem.scenarios.outdir as sio
    k, out, files = int(sys.argv[1]), sys.argv[2], eval(sys.argv[3])
    real, n = sio._rename, [0]
    def rename(src, dst):
        n[0] += 1
        if n[0] == k:
            os._exit(9)            # as kill -9 would: no cleanup, no finally
        real(src, dst)
        if k == -1 and str(dst).endswith("committed.json"):
            os._exit(9)            # killed just after the commit, before cleaning up
    sio._rename = rename
    with sio.staged_out_dir(out, force=True) as st:
        for rel, text in files.items():
            (st / rel).parent.mkdir(parents=True, exist_ok=True)
            (st / rel).write_text(text)
    print(n[0])
""")


def _killed_switch(k: int, out: Path, files: dict) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", KILLER, str(k), str(out), repr(files)],
                          capture_output=True, text=True, cwd=ROOT)


def test_a_kill_at_every_rename_leaves_the_old_or_the_new_set(tmp_path):
    """For every k, the run is killed (os._exit) at its k-th rename; the next command on
    the same --out (check_out_path, run by every command) finds --out exactly as
    before (SHA-256 of every file, manifest included) or exactly the new set, with
    the user's own file intact and no debris; and a rerun then succeeds."""
    ref_old, ref_new = tmp_path / "ref_old", tmp_path / "ref_new"
    stage(ref_old, OLD)
    (ref_old / "user.txt").write_text("the user's")
    old = snapshot(ref_old)
    shutil_copy(ref_old, ref_new)
    r = _killed_switch(0, ref_new, NEW)                    # k = 0: never killed
    n_renames = int(r.stdout)
    new = snapshot(ref_new)
    # 5 files + the manifest moved in, 3 old files + the old manifest backed up, 1 commit
    assert old != new and n_renames == 6 + 4 + 1
    outcomes = set()
    for k in range(1, n_renames + 1):
        out = tmp_path / f"out{k}"
        shutil_copy(ref_old, out)
        r = _killed_switch(k, out, NEW)
        assert r.returncode == 9, r.stderr
        sio.check_out_path(out)                   # what the next arfem command does first
        got = snapshot(out)
        assert got in (old, new), (k, got)
        outcomes.add("old" if got == old else "new")
        assert [p.name for p in out.iterdir() if p.name.startswith(".arfem-staging")] == []
        stage(out, NEW, force=True)               # the rerun is not refused
        assert snapshot(out) == new
    assert outcomes == {"old"}          # every kill before the commit rename rolls back
    out = tmp_path / "out_after_commit"
    shutil_copy(ref_old, out)
    assert _killed_switch(-1, out, NEW).returncode == 9
    sio.check_out_path(out)
    assert snapshot(out) == new         # committed: the backups are dropped, not restored


def shutil_copy(src: Path, dst: Path) -> None:
    import shutil
    shutil.copytree(src, dst)


def test_a_kill_before_a_new_out_appears_leaves_nothing(tmp_path):
    """A new --out appears by one rename: killed before it, --out does not exist and the
    staging directory beside it is removed by the next command."""
    out = tmp_path / "fresh"
    r = _killed_switch(1, out, NEW)
    assert r.returncode == 9
    sio.check_out_path(out)
    assert list(tmp_path.iterdir()) == []


def test_a_failed_rename_puts_everything_back(tmp_path, monkeypatch):
    """If a rename fails halfway (disk full), the files already moved are put back:
    --out is exactly as before and no staging debris is left."""
    out = tmp_path / "out"
    stage(out, {"b.txt": "old b"})
    before = snapshot(out)
    real, calls = sio._rename, []

    def flaky(src, dst):
        calls.append(dst)
        if len(calls) == 4:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(src, dst)
    monkeypatch.setattr(sio, "_rename", flaky)
    with pytest.raises(InputError, match="left as it was"):
        stage(out, {"a.txt": "new a", "b.txt": "new b", "c.txt": "new c"}, force=True)
    assert snapshot(out) == before
    assert sorted(p.name for p in out.iterdir()) == [sio.OWNERSHIP_MANIFEST, "b.txt"]


def test_disk_full_while_writing_is_one_line_and_out_unchanged(tmp_path, capsys,
                                                                monkeypatch):
    """ENOSPC raised by a writer inside `arfem run` (disk full): one line, exit 2, the
    earlier result in --out byte for byte as it was."""
    import arfem.scenarios.rod.outputs as runmod
    (tmp_path / "case.toml").write_text(SCENARIO)
    out = tmp_path / "out"
    assert main(["run", str(tmp_path / "case.toml"), "--out", str(out)]) == 0
    before = snapshot(out)
    capsys.readouterr()

    def full(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(runmod, "write_json", full)
    assert main(["run", str(tmp_path / "case.toml"), "--out", str(out), "--force"]) == 2
    assert "No space left on device" in one_line_error(capsys)
    assert snapshot(out) == before


# -- item 5: live staging directories are judged by their lock, not by a PID ----------

def test_live_staging_is_kept_whatever_its_pid_and_dead_one_removed(tmp_path):
    """A staging directory whose lock is held (a run in another PID namespace: its PID
    means nothing here) is left alone; once its lock is free it is removed."""
    out = tmp_path / "out"
    stage(out, {"x.txt": "1"})
    live = out / (sio._STAGE + "999999999-abc")
    (live / "new").mkdir(parents=True)
    (live / "new" / "partial.txt").write_text("being written")
    fd = os.open(live / "lock", os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        stage(out, {"x.txt": "2"}, force=True)
        assert (live / "new" / "partial.txt").exists()
    finally:
        os.close(fd)
    sio.check_out_path(out)
    assert not live.exists() and (out / "x.txt").read_text() == "2"


# -- item 4/5: names, permissions ------------------------------------------------------

def test_out_name_over_255_bytes_is_refused_before_any_work(tmp_path, capsys):
    (tmp_path / "case.toml").write_text(SCENARIO)
    out = tmp_path / ("o" * 256)
    assert main(["run", str(tmp_path / "case.toml"), "--out", str(out)]) == 2
    assert "bytes long" in one_line_error(capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.toml"]


@pytest.mark.parametrize("n", [229, 240, 255])
def test_long_out_names_that_fit_work(tmp_path, n):
    """229-255 characters: the staging name no longer grows with --out's, so they work."""
    out = tmp_path / ("o" * n)
    stage(out, {"f.txt": "x"})
    assert (out / "f.txt").read_text() == "x"
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads every directory")
def test_unreadable_directories_are_one_line(tmp_path, capsys):
    """--out or an input under a directory the user cannot enter: one line, exit 2."""
    (tmp_path / "case.toml").write_text(SCENARIO)
    locked = tmp_path / "locked"
    locked.mkdir()
    (locked / "case.toml").write_text(SCENARIO)
    locked.chmod(0)
    try:
        assert main(["run", str(tmp_path / "case.toml"), "--out", str(locked / "o")]) == 2
        assert "Permission denied" in one_line_error(capsys)
        assert main(["run", str(locked / "case.toml"), "--out", str(tmp_path / "o")]) == 2
        assert "Permission denied" in one_line_error(capsys)
    finally:
        locked.chmod(0o755)


def test_permission_errors_are_one_line_also_as_root(tmp_path, capsys, monkeypatch):
    """The same as above where the test runs as root (who may enter any directory):
    the PermissionError that stat() raises is injected."""
    import pathlib
    (tmp_path / "case.toml").write_text(SCENARIO)
    real = pathlib.Path.stat

    def stat(self, *a, **k):
        if "locked" in str(self):
            raise PermissionError(errno.EACCES, "Permission denied", str(self))
        return real(self, *a, **k)
    monkeypatch.setattr(pathlib.Path, "stat", stat)
    assert main(["run", str(tmp_path / "case.toml"), "--out",
                 str(tmp_path / "locked" / "o")]) == 2
    assert "Permission denied" in one_line_error(capsys)
    assert main(["run", str(tmp_path / "locked" / "case.toml"), "--out",
                 str(tmp_path / "o")]) == 2
    assert "Permission denied" in one_line_error(capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.toml"]


@pytest.mark.parametrize("bad", ["new\nline.toml", "nul\x01.toml", "para\u2028.toml"])
def test_a_control_character_in_a_name_keeps_the_error_one_line(tmp_path, capsys, bad):
    """A newline (or another control character) in a file name or a flag value is shown
    escaped: the error stays one line, from InputError and from argparse alike."""
    assert main(["run", str(tmp_path / bad), "--out", str(tmp_path / "o")]) == 2
    assert "file not found" in one_line_error(capsys)
    with pytest.raises(SystemExit) as ei:
        main(["diagnose", "x.toml", "--out", "o", "--frame-search", bad])
    assert ei.value.code == 2
    one_line_error(capsys)


def test_sweep_force_into_a_clone_keeps_its_readme(tmp_path, capsys, monkeypatch):
    """`arfem sweep sw.toml --out . --force` in a clone: the hand-written README.md
    (and every other file that was there) is unchanged; exit 2, one line."""
    base = SCENARIO.replace("dtau_s = 60.0", "dtau_s = 600.0")
    (tmp_path / "base.toml").write_text(base)
    (tmp_path / "sw.toml").write_text('[sweep]\nname = "s"\nbase = "base.toml"\n'
                                      "[sweep.grid]\ndtau_s = [600]\n")
    (tmp_path / "README.md").write_text("# my project\n")
    before = snapshot(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert main(["sweep", "sw.toml", "--out", ".", "--force", "--workers", "1",
                 "--no-progress"]) == 2
    assert "README.md was not written by arfem" in one_line_error(capsys)
    after = snapshot(tmp_path)
    assert {k: after.get(k) for k in before} == before


def test_adopted_outputs_of_an_older_arfem_may_be_replaced_with_force(tmp_path):
    """Results written before the ownership manifest existed (reports/*, adopted with
    adopt_outputs) are arfem's from then on: --force replaces them; a file not adopted
    is still refused."""
    out = tmp_path / "old_result"
    out.mkdir()
    (out / "summary.json").write_text("{}")
    (out / "README.md").write_text("hand-written")
    with pytest.raises(InputError, match="summary.json was not written by arfem"):
        stage(out, {"summary.json": "{1}"}, force=True)
    sio.adopt_outputs(out, ["summary.json"])
    stage(out, {"summary.json": "{1}"}, force=True)
    assert (out / "summary.json").read_text() == "{1}"
    with pytest.raises(InputError, match="README.md was not written by arfem"):
        stage(out, {"README.md": "generated"}, force=True)
    assert (out / "README.md").read_text() == "hand-written"


def test_reproduce_manifest_counts_as_arfem_files(tmp_path):
    """An `arfem reproduce` result (its MANIFEST.json: "files" with SHA-256 and
    "not_committed" names) is arfem's: owned_files lists both kinds, nothing else."""
    out = tmp_path / "paper"
    (out / "fields").mkdir(parents=True)
    (out / "README.md").write_text("r")
    (out / "fields" / "f.xdmf").write_text("x")
    (out / "mine.txt").write_text("mine")
    (out / "MANIFEST.json").write_text(json.dumps({
        "generator": "arfem reproduce", "files": {"README.md": "0" * 64},
        "not_committed": ["fields/f.xdmf"]}))
    own = sio.owned_files(out)
    assert {"README.md", "fields/f.xdmf", "MANIFEST.json"} <= set(own)
    assert "mine.txt" not in own
    stage(out, {"fields/f.xdmf": "y", "README.md": "r2"}, force=True)
    with pytest.raises(InputError, match="mine.txt was not written by arfem"):
        stage(out, {"mine.txt": "z"}, force=True)


def test_switch_into_a_directory_locked_by_its_own_process(tmp_path):
    """`arfem sweep` holds the lock on --out itself for its whole run and then stages
    its tables into it, saying so (out_locked=True): the switch must not wait for that
    lock (it did once: a deadlock). Run in a subprocess with a timeout so that a
    regression fails instead of hanging."""
    out = tmp_path / "store"
    out.mkdir()
    code = textwrap.dedent(f"""
        import arfem.scenarios.outdir as sio
        with sio.lock_out_dir({str(out)!r}, wait=False):
            with sio.staged_out_dir({str(out)!r}, force=True, out_locked=True) as st:
                (st / "results.csv").write_text("x")
        print("done")
    """)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=120, cwd=ROOT)
    assert r.returncode == 0 and "done" in r.stdout, r.stderr
    assert (out / "results.csv").read_text() == "x"


def test_two_commands_switch_one_after_the_other(tmp_path):
    """Two commands finishing into the same existing --out must not interleave their
    files and ownership manifests: while one holds the directory's lock, the other's
    switch waits (and says so on stderr), then completes with both results recorded.
    The waiting process is a real second process, as two shell commands would be."""
    from arfem.scenarios.outdir import OWNERSHIP_MANIFEST, lock_out_dir
    out = tmp_path / "out"
    out.mkdir()
    code = textwrap.dedent(f"""
        import arfem.scenarios.outdir as sio
        with sio.staged_out_dir({str(out)!r}, force=True) as st:
            (st / "b.csv").write_text("b")
        print("done", flush=True)
    """)
    with lock_out_dir(out, wait=False):
        (out / "a.csv").write_text("a")            # what the lock holder is writing
        p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, cwd=ROOT)
        note = p.stderr.readline()                 # blocks until the child waits
        assert "waiting for it to finish" in note, note
        assert p.poll() is None and not (out / "b.csv").exists()
    out_text, err = p.communicate(timeout=120)
    assert p.returncode == 0 and "done" in out_text, err
    assert (out / "b.csv").read_text() == "b" and (out / "a.csv").read_text() == "a"
    assert "b.csv" in json.loads((out / OWNERSHIP_MANIFEST).read_text())["files"]


def test_a_second_sweep_is_refused_while_the_directory_is_locked(tmp_path):
    """A sweep does not wait for a busy --out (it could be hours): one InputError."""
    from arfem.scenarios.outdir import lock_out_dir
    from arfem.scenarios.sweep.store import DirLock
    with lock_out_dir(tmp_path, wait=False):
        with pytest.raises(InputError, match="another arfem command"):
            with DirLock(tmp_path):
                pass
    with DirLock(tmp_path):                        # free again once released
        pass


def test_a_run_that_found_out_absent_does_not_fill_it_after_another_did(tmp_path):
    """Without --force, an --out that was absent (or empty) when the command started must
    not receive its files after another command filled it meanwhile: the check made
    before the work is made again under the lock, at the switch (an audit found the
    second of two concurrent `arfem run`s silently replacing the first's results).
    With --force the later command replaces arfem's own files, as it would in turn."""
    out = tmp_path / "new"
    with pytest.raises(InputError, match="another command wrote there"):
        with sio.staged_out_dir(out) as st:          # found absent: no --force needed
            (st / "summary.json").write_text("mine")
            with sio.staged_out_dir(out) as other:   # another command finishes first
                (other / "summary.json").write_text("theirs")
    assert (out / "summary.json").read_text() == "theirs"
    assert not [p for p in tmp_path.iterdir() if p.name != "new"]   # no staging left
    with sio.staged_out_dir(out, force=True) as st:
        (st / "summary.json").write_text("mine")
    assert (out / "summary.json").read_text() == "mine"
