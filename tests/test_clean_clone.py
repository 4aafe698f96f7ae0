"""A fresh clone stays clean after the README's first command (``arfem reproduce``).

Properties verified: the committed ``reports/paper`` comes out byte-identical after a
rerun in a copy made as a clone makes it (the committed files only, no ownership file
of an earlier run); a regenerated picture within one grey level of the committed one
keeps the committed bytes (another renderer moving an anti-aliased edge), and one that
differs by more is written (a real change is never hidden); the page lists no package
version but arfem's (a clone on other numpy/scipy versions must stay clean).
"""
from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from arfem.scenarios.cli import main
from arfem.scenarios.rod.deterministic import same_picture

ROOT = Path(__file__).resolve().parents[1]
COMMITTED = ROOT / "reports" / "paper"


def _clone(dst: Path) -> list[str]:
    """The committed files of reports/paper copied to ``dst`` (as ``git clone`` gives
    them: MANIFEST.json and the files it lists, nothing ignored)."""
    man = json.loads((COMMITTED / "MANIFEST.json").read_text("utf-8"))
    rels = sorted(man["files"]) + ["MANIFEST.json"]
    for r in rels:
        (dst / r).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(COMMITTED / r, dst / r)
    return rels


def _bytes(d: Path, rels) -> dict:
    return {r: (d / r).read_bytes() for r in rels}


def _shift(png: Path, levels: int, n: int = 40) -> None:
    """Move ``n`` pixels of ``png`` by ``levels`` grey levels, as another renderer's
    anti-aliasing would."""
    with Image.open(png) as im:
        a = np.asarray(im.convert("RGBA")).copy()
    idx = np.linspace(0, a.shape[0] * a.shape[1] - 1, n).astype(int)
    flat = a.reshape(-1, 4)
    flat[idx, :3] = np.where(flat[idx, :3] >= 255 - levels, flat[idx, :3] - levels,
                             flat[idx, :3] + levels)
    Image.fromarray(a).save(png)


def _committed_elsewhere(out: Path, levels: int, monkeypatch) -> dict:
    """``arfem reproduce`` into ``out`` on "another machine", whose renderer draws every
    figure.png ``levels`` grey levels off in 40 pixels, then ``out`` as a clone of that
    commit gives it (no ownership file, no field files); returns its files' bytes."""
    from arfem.scenarios.rod import outputs as run_outputs
    draw = run_outputs._figure

    def other_renderer(ev, path):
        draw(ev, path)
        _shift(Path(path), levels)
    with monkeypatch.context() as m:
        m.setattr(run_outputs, "_figure", other_renderer)
        assert main(["reproduce", "--out", str(out)]) == 0
    (out / ".arfem-outputs.json").unlink()
    for name in ("paper_fig2", "paper_fig3"):
        shutil.rmtree(out / name / "fields")
    rels = sorted(json.loads((out / "MANIFEST.json").read_text("utf-8"))["files"])
    return _bytes(out, rels + ["MANIFEST.json"])


@pytest.fixture(scope="module")
def clone(tmp_path_factory):
    d = tmp_path_factory.mktemp("clone") / "paper"
    rels = _clone(d)
    before = _bytes(d, rels)
    assert main(["reproduce", "--out", str(d)]) == 0
    return d, rels, before


def test_the_committed_reports_are_rewritten_byte_for_byte(clone):
    """Every committed file (both figures and 3D pictures per scenario, the CSVs, JSON,
    README, report.html and MANIFEST.json) is identical after ``arfem reproduce`` in a
    fresh copy: ``git status`` stays clean."""
    d, rels, before = clone
    after = _bytes(d, rels)
    assert [r for r in rels if after[r] != before[r]] == []
    page = (d / "report.html").read_text("utf-8")
    assert "<th>arfem</th>" in page and "<th>numpy</th>" not in page


def test_a_picture_one_grey_level_off_keeps_the_committed_bytes(clone, tmp_path,
                                                                monkeypatch):
    """A commit made where the renderer drew each figure one grey level off in 40 pixels
    is left byte-identical by ``arfem reproduce`` here (the figures keep their
    committed bytes, so MANIFEST.json and report.html, which embeds them, do too);
    three grey levels off, the figures are regenerated and exactly those files change."""
    d = clone[0]
    fresh = (d / "paper_fig2" / "figure.png").read_bytes()
    for levels in (1, 3):
        w = tmp_path / f"off{levels}"
        before = _committed_elsewhere(w, levels, monkeypatch)
        assert before["paper_fig2/figure.png"] != fresh
        assert same_picture(w / "paper_fig2" / "figure.png",
                            d / "paper_fig2" / "figure.png") is (levels == 1)
        assert main(["reproduce", "--out", str(w)]) == 0
        changed = sorted(r for r in before if (w / r).read_bytes() != before[r])
        if levels == 1:
            assert changed == []
        else:
            assert changed == ["MANIFEST.json", "paper_fig2/figure.png",
                               "paper_fig3/figure.png", "report.html"]
            assert (w / "paper_fig2" / "figure.png").read_bytes() == fresh
