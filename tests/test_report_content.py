"""What a user reads in the reports of a mesh run and of its compensation replay
(issue 42 item 8), on the small box mesh of ``geometry_meshes`` (each run ~1 s of CPU).

Properties verified: the run's report.html shows its title once, its sensors as a
rounded table (no 17-digit arrays: a sensor's history is summarised by its count, ends
and range), every number rounded; the replay of a run's own record says the record is
the model's own output, names the model and the record it replayed (links that
resolve), labels no curve "measured", says "rpm" and not "1/min"; ``run --help`` lists
exactly the files each kind of run writes; in Chromium, no table of the replay's page
is cut at 1280 px (each box as wide as its table).
"""
from __future__ import annotations

import html
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest

from arfem.scenarios.cli import build_parser, main
from geometry_meshes import BOX_TOML, box_meshio, write_msh

SPEEDY = BOX_TOML.replace("[outputs]\nfields = false\npicture = false\n", "")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A box run (default outputs: no fields, the picture) and the replay of its own
    record with its own model."""
    d = tmp_path_factory.mktemp("report_content")
    write_msh(box_meshio(), d / "box.msh")
    (d / "box.toml").write_text(SPEEDY, encoding="utf-8")
    assert main(["run", str(d / "box.toml"), "--out", str(d / "run")]) == 0
    assert main(["compensate", str(d / "run" / "model.json"), str(d / "run" / "record.toml"),
                 "--out", str(d / "comp")]) == 0
    return d


def _cells(page: str) -> list[str]:
    return [html.unescape(re.sub("<[^>]+>", "", c))
            for c in re.findall(r"<t[dh][^>]*>(.*?)</t[dh]>", page, flags=re.S)]


def test_a_mesh_run_writes_no_fields_by_default_and_its_picture(runs):
    """[outputs] fields is off unless asked for (it doubles the memory of a run); the
    picture of the groups is on."""
    out = runs / "run"
    assert not (out / "fields").exists()
    assert (out / "geometry.png").stat().st_size > 10_000


def test_the_run_report_reads_as_a_table_not_raw_json(runs):
    """One title; every number in the tables at most 6 significant digits; a sensor's
    13-value history shown as its count, ends and range; the page smaller than the
    JSON it shows would make it."""
    page = (runs / "run" / "report.html").read_text("utf-8")
    title = re.search(r"<h1>(.*?)</h1>", page).group(1)
    assert page.count("<h1>") == 1 and page.count(f">{title}<") == 2    # <title> and <h1>
    cells = _cells(page)
    floats = [t for c in cells for t in re.findall(r"\d+\.\d+(?:e[-+]?\d+)?", c)]
    digits = [t.split("e")[0].replace(".", "").lstrip("0") for t in floats]
    assert len(floats) > 20 and max(map(len, digits)) <= 6, max(floats, key=len)
    values = [c for c in cells if c.startswith("13 values, ")]
    assert len(values) == 3, values                   # time_s, tip_x, mid
    assert any(re.fullmatch(r"13 values, 20 … [\d.]+ \(min 20, max 24\.\d+\)", c)
               for c in values), values


def test_the_replay_of_a_runs_own_record_says_so_and_names_its_inputs(runs):
    """The verdict says the record is the model's own output (a 100 % that measures the
    arithmetic); the model and the record are named and linked, and the links resolve
    from the report; the page no longer says 'No input file is recorded'."""
    md = (runs / "comp" / "summary.md").read_text("utf-8")
    verdict = md.split("## Verdict", 1)[1].split("|", 1)[0]
    assert "The record is the model's own output" in verdict
    assert "run/record.toml" in md and "run/model.json" in md
    page = (runs / "comp" / "report.html").read_text("utf-8")
    hrefs = re.findall(r'href="([^"]+)"', page)
    for name in ("model.json", "record.toml"):
        link = next(h for h in hrefs if h.endswith("run/" + name))
        assert (runs / "comp" / link).resolve() == (runs / "run" / name).resolve()
    assert "measured +" not in md and "(measured)" not in md


def test_the_replay_figure_says_record_and_rpm(runs, monkeypatch):
    """The curves of the replay's figure are the record's and the record + offset (not
    'measured'), and the speed axis reads rpm, as on every other page."""
    from matplotlib.figure import Figure
    from arfem.io import read_toml  # noqa: F401  (the record is read by the command)
    from arfem.scenarios.records.axes_record import load_axes_record
    from arfem.scenarios.compensation.model_file import read_model
    from arfem.scenarios.compensation.replay import replay
    from arfem.scenarios.compensation.report import replay_figure
    model = read_model(runs / "run" / "model.json")
    res = replay(model, load_axes_record(runs / "run" / "record.toml"))
    drawn = []
    monkeypatch.setattr(Figure, "savefig", lambda self, *a, **k: drawn.append(self))
    replay_figure(res, runs / "unused.png")
    texts = [t.get_text() for ax in drawn[0].axes for t in
             [ax.yaxis.label, ax.title] + (ax.get_legend().get_texts() if ax.get_legend()
                                           else [])]
    joined = " ".join(texts)
    assert "speed [rpm]" in joined and "1/min" not in joined
    assert "measured" not in joined and "the record's d_tip_x_um" in joined


def _files_named(text: str) -> set:
    return set(re.findall(r"[\w/]+\.(?:csv|json|png|md|toml|html|xdmf3|h5|xdmf)\b", text))


def test_run_help_lists_exactly_what_each_kind_of_run_writes():
    """``arfem run --help``: the rod's paragraph names run_outputs.WRITES and the mesh's
    geometry_scenario.WRITES, each file once and no other (a mesh run writes
    report.html and sensors.png, not timeseries.csv or figure.png)."""
    from arfem.scenarios.geometry.scenario import WRITES as MESH
    from arfem.scenarios.rod.outputs import WRITES as ROD
    text = " ".join(build_parser("run")._subparsers._group_actions[0]
                    .choices["run"].description.split())
    rod, mesh = text.split("A mesh scenario", 1)
    rod = rod.split("The paper's rod", 1)[1]
    assert _files_named(rod) == set(ROD)
    assert _files_named(mesh) - {"scenarios/data/spindle_unit.toml"} == set(MESH)
    assert {"report.html", "sensors.png"} <= _files_named(mesh)
    assert not {"timeseries.csv", "figure.png"} & _files_named(mesh)


def _chromium():
    return shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(_chromium() is None, reason="no chromium on PATH (.ci/run installs it)")
def test_no_table_of_the_replay_page_is_cut_at_1280_px(runs):
    """Every table box of the replay's page is as wide as its table at 1280 px (none
    scrolls: nothing is hidden to the right), Chromium's own layout read back."""
    report = runs / "comp" / "report.html"
    probe = report.with_name("probe.html")
    probe.write_text(
        f'<html><body style="margin:0"><iframe id="f" src="{report.name}" '
        'style="width:1280px;height:900px;border:0"></iframe><script>'
        "document.getElementById('f').addEventListener('load',()=>{"
        "const d=document.getElementById('f').contentWindow.document;"
        "const cut=[...d.querySelectorAll('div.wide')].filter(b=>b.scrollWidth>b.clientWidth+1)"
        ".map(b=>b.textContent.slice(0,40));"
        "const p=document.createElement('pre');p.id='w';"
        "p.textContent=JSON.stringify([d.querySelectorAll('div.wide').length,cut]);"
        "document.body.appendChild(p)})</script></body></html>", encoding="utf-8")
    try:
        with tempfile.TemporaryDirectory() as prof:
            res = subprocess.run([
                _chromium(), "--headless", "--no-sandbox", "--disable-gpu",
                "--disable-background-networking", "--no-first-run",
                f"--user-data-dir={prof}", "--allow-file-access-from-files",
                "--window-size=1400,1000", "--virtual-time-budget=5000", "--dump-dom",
                probe.as_uri()], capture_output=True, text=True, timeout=120)
    finally:
        probe.unlink()
    import json
    dom = res.stdout
    start = dom.index('<pre id="w">') + len('<pre id="w">')
    n, cut = json.loads(html.unescape(dom[start:dom.index("</pre>", start)]))
    assert n >= 4 and cut == [], cut


def test_the_replay_page_lists_the_model_and_the_record_as_its_inputs(runs):
    """The page's inputs section links the model and the record the replay names (it
    said 'No input file is recorded in this directory')."""
    page = (runs / "comp" / "report.html").read_text("utf-8")
    inputs = page.split('<h2 id="inputs">', 1)[1].split("<h2", 1)[0]
    assert "No input file is recorded" not in inputs
    assert "run/model.json" in inputs and "run/record.toml" in inputs
