"""report.html: one self-contained page for any arfem output directory.

Parsed with html.parser everywhere; loaded in a real headless Chromium where one is
installed (the browser test is skipped elsewhere, e.g. on CI).
"""
from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import tempfile
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote

import pytest

from arfem.scenarios.cli import main
from arfem.scenarios.html_report import write_html_report
from scenario_texts import small_scenario

SMALL = small_scenario("small <&> run", fields=True, picture=True, field_interval_s=1800.0)


class _Page(HTMLParser):
    """Collects images, links, tables and text cells of a page."""

    def __init__(self):
        super().__init__()
        self.imgs, self.links, self.tags, self.cells = [], [], [], []
        self.scripts = 0
        self._cell = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.append(tag)
        if tag == "img":
            self.imgs.append(a.get("src", ""))
        elif tag == "a":
            self.links.append(a.get("href", ""))
        elif tag == "script":
            self.scripts += 1
        elif tag in ("td", "th"):
            self._cell = ""

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self.cells.append(self._cell)
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data


def _parse(path: Path) -> _Page:
    p = _Page()
    p.feed(path.read_text("utf-8"))
    return p


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("run")
    case = d / "case.toml"
    case.write_text(SMALL, encoding="utf-8")
    out = d / "out"
    assert main(["run", str(case), "--out", str(out)]) == 0
    return out


def assert_self_contained(report: Path) -> _Page:
    """Every image is an embedded PNG, every link resolves to a file, no script."""
    page = _parse(report)
    assert page.scripts == 0
    assert "table" in page.tags
    for src in page.imgs:
        assert src.startswith("data:image/png;base64,"), src[:40]
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
    for href in page.links:
        if href.startswith("#"):
            continue
        assert "://" not in href and not href.startswith("/"), href   # relative only
        assert (report.parent / unquote(href)).is_file(), href
    return page


def test_run_writes_a_self_contained_report(run_dir):
    """`arfem run` ends with report.html: both figures embedded, the summary numbers as
    the JSON has them (rounded to 6 significant digits), the scenario input, the versions, and a
    link to every data file (CSV, JSON, XDMF, HDF5); all text escaped (the scenario
    name holds <&>)."""
    report = run_dir / "report.html"
    page = assert_self_contained(report)
    assert len(page.imgs) == 2                       # figure.png, temperature_3d.png
    summary = json.loads((run_dir / "summary.json").read_text("utf-8"))
    for key in ("fem_peak_um", "max_abs_diff_um", "C1", "C1_fitted", "rmse_um"):
        assert f"{summary[key]:.6g}" in page.cells, key   # rounded for reading
    for f in ("timeseries.csv", "summary.json", "fields/fields.xdmf3", "fields/fields.h5",
              "fields/peak.xdmf", "scenario.toml"):
        assert f in page.links, f
    text = report.read_text("utf-8")
    assert "small &lt;&amp;&gt; run" in text and "small <&> run" not in text
    assert "numpy" in page.cells and "scikit-fem" in page.cells
    assert "field_interval_s = 1800.0" in text       # the input, verbatim


def test_report_discovers_other_layouts(tmp_path):
    """A diagnose-like and a sweep-like directory: nested JSON as tables, records as a
    table, a dataset named in the JSON (outside the directory) linked relatively, a
    folder of many point files listed rather than tabulated; hostile keys escaped."""
    data = tmp_path / "data"
    data.mkdir()
    (data / "case.toml").write_text("[dataset]\nname = 'x'\n", encoding="utf-8")
    diag = tmp_path / "diag"
    diag.mkdir()
    (diag / "diagnosis.json").write_text(json.dumps({
        "dataset": str(data / "case.toml"), "cause": "h_drift",
        "baseline": {"rmse_um": 1.25, "per_phase": [{"phase": 0, "rmse_um": 0.5},
                                                    {"phase": 1, "rmse_um": 2.0, "n": 7}]},
        "<script>alert(1)</script>": 3}), encoding="utf-8")
    (diag / "report.md").write_text(
        "# Diagnosis of x\n\ntext with [the data](../data/case.toml) and "
        "[a dead link](nowhere.csv)\n\n| channel | rmse [µm] | max \\|error\\| [µm] |\n|---|---|---|\n"
        "| ch<1> | 0.75 | 1.5 |\n",
        encoding="utf-8")
    sweep = tmp_path / "sweep"
    (sweep / "points").mkdir(parents=True)
    for i in range(30):
        (sweep / "points" / f"{i:03d}.json").write_text(json.dumps({"i": i}), encoding="utf-8")
    (sweep / "results.csv").write_text("h_W_m2K,err_pct\n5,0.1\n", encoding="utf-8")

    r = write_html_report(diag)
    page = assert_self_contained(r)
    text = r.read_text("utf-8")
    assert "<script>" not in text and "&lt;script&gt;" in text
    assert "1.25" in page.cells and "h_drift" in page.cells and "2" in page.cells
    assert "../data/case.toml" in page.links
    assert "<title>Diagnosis of x</title>" in text
    assert "<td>ch&lt;1&gt;</td>" in text and "0.75" in page.cells   # the Markdown table
    assert "max |error| [µm]" in page.cells                           # an escaped bar
    assert "nowhere.csv" not in page.links              # links only to files that exist

    r = write_html_report(sweep)
    page = assert_self_contained(r)
    assert "30 JSON files" in r.read_text("utf-8")
    assert "points/007.json" in page.links and "results.csv" in page.links
    assert write_html_report(sweep).read_bytes() == r.read_bytes()   # no timestamp in it
    assert "<th>size</th>" in r.read_text("utf-8")
    assert "<th>size</th>" not in write_html_report(sweep, file_sizes=False).read_text("utf-8")


def test_report_command(tmp_path, capsys):
    """`arfem report DIR` writes the page; a missing DIR is one error line, status 2."""
    (tmp_path / "summary.json").write_text('{"a_um": 1.5}', encoding="utf-8")
    from arfem.scenarios.outdir import adopt_outputs
    adopt_outputs(tmp_path, ["summary.json"])      # an arfem folder (issue 29: only there)
    assert main(["report", str(tmp_path)]) == 0
    assert (tmp_path / "report.html").is_file()
    assert main(["report", str(tmp_path / "nope")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("arfem: error:") and "not a directory" in err[0]


# -- a real browser ------------------------------------------------------------------------

_CHECK = """<script>
window.__errs = [];
window.addEventListener('error', function (e) {
  window.__errs.push(e.message || ('resource: ' + (e.target && (e.target.src || e.target.href))));
}, true);
var _ce = console.error; console.error = function () { window.__errs.push([].join.call(arguments, ' ')); _ce.apply(console, arguments); };
window.addEventListener('load', function () {
  var imgs = [].slice.call(document.images);
  var r = {n: imgs.length, decoded: imgs.filter(function (i) { return i.complete && i.naturalWidth > 0; }).length,
           errors: window.__errs, tables: document.querySelectorAll('table').length};
  var pre = document.createElement('pre'); pre.id = 'arfem-check'; pre.textContent = JSON.stringify(r);
  document.body.appendChild(pre);
});
</script>"""


def _chromium():
    return shutil.which("chromium") or shutil.which("chromium-browser")


def _chromium_args(profile):
    return [_chromium(), "--headless", "--no-sandbox", "--disable-gpu",
            "--disable-background-networking", "--disable-component-update", "--disable-sync",
            "--no-first-run", f"--user-data-dir={profile}", "--hide-scrollbars"]


@pytest.mark.skipif(_chromium() is None, reason="no chromium on PATH (.ci/run installs it)")
def test_report_in_headless_chromium(run_dir, tmp_path):
    """In Chromium the page loads without console or resource errors, every image
    decodes (naturalWidth > 0), and its screenshot is not blank.

    The check script is added to a copy of the page (the report itself has no script);
    the browser console of the unmodified page is read from Chromium's log as well.
    """
    import matplotlib.image as mpimg
    report = run_dir / "report.html"
    probe = run_dir / ".probe.html"          # beside it, so relative links still resolve
    text = report.read_text("utf-8")
    probe.write_text(text.replace("<head>", "<head>" + _CHECK, 1), encoding="utf-8")
    try:
        with tempfile.TemporaryDirectory() as prof:
            res = subprocess.run(_chromium_args(prof) + ["--virtual-time-budget=10000",
                                                         "--dump-dom", probe.as_uri()],
                                 capture_output=True, text=True, timeout=120)
    finally:
        probe.unlink()
    dom = res.stdout
    start = dom.index('<pre id="arfem-check">') + len('<pre id="arfem-check">')
    import html as _html
    check = json.loads(_html.unescape(dom[start:dom.index("</pre>", start)]))
    assert check["n"] == 2 and check["decoded"] == 2, check
    assert check["errors"] == [], check
    assert check["tables"] >= 3
    shot = tmp_path / "shot.png"
    with tempfile.TemporaryDirectory() as prof:
        res = subprocess.run(_chromium_args(prof) + [
            "--enable-logging=stderr", "--v=0", "--window-size=1200,2000",
            f"--screenshot={shot}", report.as_uri()], capture_output=True, text=True,
            timeout=120)
    console = [ln for ln in res.stderr.splitlines() if "CONSOLE" in ln]
    assert console == [], console
    img = mpimg.imread(shot)
    assert img.shape[0] >= 1000 and img[..., :3].std() > 0.05   # not a blank page
    os.environ.get("ARFEM_KEEP_SHOT") and shutil.copy(shot, os.environ["ARFEM_KEEP_SHOT"])


def _wide_folder(root: Path) -> Path:
    """A diagnose-like folder: report.md with a verdict, a 16-column table and a long
    unbroken name; a JSON with a wide list of records."""
    root.mkdir()
    cols = [f"T_thermometer_{i}_C" for i in range(16)]
    table = ["| " + " | ".join(cols) + " |", "|" + "---|" * 16,
             "| " + " | ".join("0.123456" for _ in cols) + " |"]
    (root / "report.md").write_text(
        "# Diagnosis\n\n## Verdict\n\nThe one verdict sentence XYZZY.\n\n## Details\n\n"
        + "\n".join(table) + "\n\n`" + "a_very_long_unbroken_name_" * 8 + "`\n",
        encoding="utf-8")
    (root / "diagnosis.json").write_text(json.dumps(
        {"causes": [{c: 1.0 for c in cols}, {c: 2.0 for c in cols}]}), encoding="utf-8")
    write_html_report(root)
    return root / "report.html"


def test_verdict_is_shown_once_and_tables_scroll_in_their_own_box(tmp_path):
    """Issue 30 item 8: the verdict came twice (the box, then report.md rendered), and
    wide tables made the whole page scroll sideways. Every table now sits in a box that
    scrolls by itself, and report.md is rendered without its verdict section."""
    text = _wide_folder(tmp_path / "d").read_text("utf-8")
    assert text.count("XYZZY") == 1 and "Shown at the top of this page" in text
    assert text.count("<table") == text.count('<div class="wide"><table') >= 3
    assert ".wide{max-width:100%;overflow-x:auto}" in text and "img{max-width:100%" in text


@pytest.mark.skipif(_chromium() is None, reason="no chromium on PATH (.ci/run installs it)")
@pytest.mark.parametrize("width", [1280, 390])
def test_report_does_not_scroll_sideways_in_chromium(tmp_path, width):
    """At a laptop's (1280 px) and a phone's (390 px) width the page is no wider than
    the window: Chromium's own layout, read back from the DOM. The page is laid out in
    an iframe of that width (headless Chromium's window is at least 500 px wide)."""
    report = _wide_folder(tmp_path / "d")
    probe = report.with_name("probe.html")
    probe.write_text(
        f'<html><body style="margin:0"><iframe id="f" src="{report.name}" '
        f'style="width:{width}px;height:900px;border:0"></iframe><script>'
        "document.getElementById('f').addEventListener('load',()=>{"
        "const w=document.getElementById('f').contentWindow;"
        "const p=document.createElement('pre');p.id='w';"
        "p.textContent=w.document.documentElement.scrollWidth+' '+w.innerWidth;"
        "document.body.appendChild(p)})</script></body></html>", encoding="utf-8")
    with tempfile.TemporaryDirectory() as prof:
        res = subprocess.run(_chromium_args(prof) + [
            "--allow-file-access-from-files", "--window-size=1400,1000",
            "--virtual-time-budget=5000", "--dump-dom", probe.as_uri()],
            capture_output=True, text=True, timeout=120)
    dom = res.stdout
    start = dom.index('<pre id="w">') + len('<pre id="w">')
    scroll, inner = map(int, dom[start:dom.index("</pre>", start)].split())
    assert inner == width and scroll <= inner, (scroll, inner)
