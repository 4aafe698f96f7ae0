"""One self-contained ``report.html`` for any arfem output directory: the library behind
``arfem report DIR`` (:mod:`arfem.scenarios.commands.report`) and every command that writes a folder.

Data flow: an output directory (of ``run``, ``reproduce``, ``diagnose``, ``sweep`` or
``allocate``) → discovery of what is in it → ``DIR/report.html``. Nothing is assumed
about which command wrote the directory:

* every PNG is embedded as a ``data:`` URI (the page needs no other file to show
  its figures);
* every JSON file becomes tables of its numbers, rounded for reading (6 significant
  digits; the JSON file has every digit); a list of more than
  :data:`MAX_LIST_SHOWN` numbers (a sensor's history) is summarised by its count,
  first and last values and range rather than printed; a folder with many JSON files
  (a sweep's ``points/``) is listed, not tabulated;
* the inputs: TOML files in the directory (``scenario.toml``, a copied dataset
  description) are shown verbatim, and any ``.toml`` / ``.csv`` file a JSON file
  names (``"source"``, ``"dataset"``, ...) that exists is linked;
* Markdown files (``summary.md``, ``README.md``) are rendered (headings, lists, pipe
  tables; links only to files that exist), open for the top folder (its title, which
  is the page's, not repeated; its pictures shown where it places them), collapsed
  below;
* every other file (CSV, JSON, XDMF, HDF5) is linked by its relative path with its
  size, so the links work wherever the directory is moved;
* the versions of the software that wrote the report.

The page is static (no script, no server, no network), every text is escaped with
:func:`html.escape`, and it is written atomically. It holds no timestamp, so the same
directory gives the same bytes.
"""
from __future__ import annotations

import base64
import html
import json
import os
import platform
import re
from pathlib import Path
from urllib.parse import quote, unquote

from markdown_it import MarkdownIt

from arfem.io import atomic_write_text
from arfem.params import InputError
from arfem.scenarios.outdir import final_out_dir

__all__ = ["write_html_report", "REPORT_NAME"]

REPORT_NAME = "report.html"
#: a folder with more JSON files than this is listed, not tabulated (a sweep's points/)
MAX_JSON_TABLES = 12
#: rows of a list-of-records table shown before the rest is cut (the JSON file has all)
MAX_ROWS = 60
#: a PNG above this size is linked instead of embedded [bytes]
MAX_EMBED = 8_000_000
#: JSON files above this size are linked, not tabulated [bytes]
MAX_JSON = 2_000_000
#: a list of numbers longer than this is summarised (count, first, last, range)
MAX_LIST_SHOWN = 8
#: significant digits of the numbers shown (the JSON files keep every digit)
DIGITS = 6
#: a list of at most half this many records with more keys than this is transposed
MAX_COLUMNS = 8
_PACKAGES = ("arfem", "numpy", "scipy", "scikit-fem", "matplotlib", "meshio", "h5py",
             "pyvista", "vtk", "statsmodels", "pymoo", "dask", "tqdm")
_INPUT_KEYS = (".toml", ".csv")

_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:2em auto;
max-width:1100px;padding:0 1em;color:#222;line-height:1.4;overflow-wrap:break-word}
.wide{max-width:100%;overflow-x:auto}img{max-width:100%;height:auto}
@media (max-width:600px){body{margin:1em auto;padding:0 .6em}table{font-size:.8em}
td{overflow-wrap:anywhere}}
h1{font-size:1.5em}.verdict{background:#f3f7fb;border-left:4px solid #2a6ebb;
padding:.2em 1em .6em;margin:1em 0 2em}.verdict h2{margin-top:.6em;border:0}h2{font-size:1.25em;border-bottom:1px solid #ccc;padding-bottom:.2em;
margin-top:2em}h3{font-size:1.05em;margin-top:1.4em}
table{border-collapse:collapse;margin:.5em 0 1em;font-size:.88em}
th,td{border:1px solid #ccc;padding:.2em .5em;text-align:left;vertical-align:top}
td code,th code{overflow-wrap:anywhere}table.records td{white-space:nowrap}
th{background:#f2f2f2}td.num{text-align:right;font-variant-numeric:tabular-nums}
figure{margin:1em 0}figure img,.verdict img{max-width:100%;height:auto;border:1px solid #ddd}
figcaption{font-size:.85em;color:#555}pre{background:#f7f7f7;padding:.6em;overflow-x:auto;
font-size:.82em}details{margin:.4em 0}code{font-size:.9em}.note{color:#666;font-size:.85em}
"""


def _e(x) -> str:
    return html.escape(str(x), quote=True)


def _href(rel: Path) -> str:
    return quote(rel.as_posix())


def _size(n: int) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000.0
    return f"{n} B"  # pragma: no cover


def _scalar(v) -> str:
    """A JSON value as text: a float to :data:`DIGITS` significant digits.

    >>> _scalar(-27.713338249561137), _scalar(1.2e-11), _scalar(86400.0), _scalar(3)
    ('-27.7133', '1.2e-11', '86400', '3')
    """
    if v is None:
        return "–"
    if isinstance(v, bool):
        return json.dumps(v)
    if isinstance(v, float):
        return f"{v:.{DIGITS}g}"
    if isinstance(v, (int, str)):
        return str(v)
    if isinstance(v, list) and all(_is_number(x) for x in v):
        return _numbers(v)
    if isinstance(v, list) and v and all(isinstance(x, list) for x in v):
        return _matrix(v)
    return json.dumps(v, ensure_ascii=False)


def _matrix(v: list) -> str:
    """A nested list of numbers (a model's matrix) as its shape and range.

    >>> _matrix([[0.99195, 0.0025], [-0.0006, 0.98]])
    '2 × 2 values (min -0.0006, max 0.99195)'
    """
    import numpy as np
    try:
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError):               # ragged, or not numbers
        return json.dumps(v, ensure_ascii=False)[:300]
    if a.size == 0:
        return " × ".join(map(str, a.shape)) + " values"
    return (" × ".join(map(str, a.shape)) + f" values (min {_scalar(float(a.min()))}, "
            f"max {_scalar(float(a.max()))})")


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _numbers(v: list) -> str:
    """A list of numbers, rounded; a long one as its count, ends and range.

    >>> _numbers([0.0, 0.0, -0.08])
    '[0, 0, -0.08]'
    >>> _numbers([float(i) * 60 for i in range(1441)])
    '1441 values, 0 … 86400 (min 0, max 86400)'
    """
    if len(v) <= MAX_LIST_SHOWN:
        return "[" + ", ".join(_scalar(x) for x in v) + "]"
    return (f"{len(v)} values, {_scalar(v[0])} … {_scalar(v[-1])} "
            f"(min {_scalar(min(v))}, max {_scalar(max(v))})")


def _is_scalar(v) -> bool:
    return v is None or isinstance(v, (bool, int, float, str))


def _cell(v) -> str:
    cls = ' class="num"' if _is_number(v) else ""
    return f"<td{cls}>{_e(_scalar(v))}</td>"


def _flatten(obj: dict, prefix: str = "") -> tuple[list, list]:
    """(dotted scalar rows, [(title, list of records)]) of a JSON object."""
    rows, tables = [], []
    for k, v in obj.items():
        key = f"{prefix}{k}"
        if _is_scalar(v):
            rows.append((key, v))
        elif isinstance(v, dict):
            r, t = _flatten(v, key + ".")
            rows += r
            tables += t
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            tables.append((key, v))
        elif isinstance(v, list) and v and (all(_is_number(x) for x in v)
                                            or all(isinstance(x, list) for x in v)):
            rows.append((key, _scalar(v)))
        elif isinstance(v, list) and all(_is_scalar(x) for x in v):
            shown = ", ".join(_scalar(x) for x in v[:MAX_ROWS])
            more = f" … ({len(v)} values in all)" if len(v) > MAX_ROWS else ""
            rows.append((key, shown + more if v else "[]"))
        else:
            rows.append((key, json.dumps(v, ensure_ascii=False)[:2000]))
    return rows, tables


def _kv_table(rows) -> str:
    body = "".join(f"<tr><th>{_e(k)}</th>{_cell(v)}</tr>" for k, v in rows)
    return f'<table class="kv"><tr><th>key</th><th>value</th></tr>{body}</table>'


def _records_table(records: list) -> str:
    """A list of records as a table: one row per record; a few records with many keys
    (a replay's axes) transposed, one column per record, so that the table fits a
    laptop's width instead of scrolling sideways."""
    cols: list = []
    for r in records[:MAX_ROWS]:
        for k in r:
            if k not in cols:
                cols.append(k)

    def cell(r, c):
        if c not in r:
            return "<td></td>"
        return _cell(r[c]) if _is_scalar(r[c]) else f"<td>{_e(_scalar(r[c])[:300])}</td>"
    if len(cols) > MAX_COLUMNS and len(records) <= MAX_COLUMNS // 2:
        body = "".join(f"<tr><th>{_e(c)}</th>" + "".join(cell(r, c) for r in records)
                       + "</tr>" for c in cols)
        return f'<table class="records">{body}</table>'
    head = "".join(f"<th>{_e(c)}</th>" for c in cols)
    body = "".join("<tr>" + "".join(cell(r, c) for c in cols) + "</tr>"
                   for r in records[:MAX_ROWS])
    more = (f'<p class="note">first {MAX_ROWS} of {len(records)} rows; the JSON file '
            "has all</p>" if len(records) > MAX_ROWS else "")
    return f'<table class="records"><tr>{head}</tr>{body}</table>{more}'


def _json_section(path: Path, rel: Path, inputs: dict, root: Path) -> str:
    if path.stat().st_size > MAX_JSON:
        return (f'<p class="note"><a href="{_href(rel)}">{_e(rel.as_posix())}</a> '
                f"({_size(path.stat().st_size)}): too large to tabulate</p>")
    try:
        data = json.loads(path.read_text("utf-8"))
    except (OSError, ValueError) as exc:
        return f'<p class="note">{_e(rel.as_posix())}: not readable as JSON ({_e(exc)})</p>'
    _find_inputs(data, path.parent, root, inputs)
    out = f'<h3 id="{_e(_anchor(rel))}">{_e(rel.as_posix())}</h3>'
    if isinstance(data, list) and data and all(isinstance(x, dict) for x in data):
        return out + _records_table(data)
    if not isinstance(data, dict):
        return out + _kv_table([("value", data)]) if _is_scalar(data) else \
            out + f"<pre>{_e(json.dumps(data, ensure_ascii=False, indent=1)[:5000])}</pre>"
    rows, tables = _flatten(data)
    if rows:
        out += _kv_table(rows)
    for title, recs in tables:
        out += f"<p><b>{_e(title)}</b></p>" + _records_table(recs)
    return out


def _find_inputs(obj, base: Path, root: Path, inputs: dict, depth: int = 0) -> None:
    """Record files a JSON names that look like inputs (.toml, .csv) and exist."""
    if depth > 3:
        return
    if isinstance(obj, dict):
        for v in obj.values():
            _find_inputs(v, base, root, inputs, depth + 1)
    elif isinstance(obj, list):
        for v in obj[:50]:
            _find_inputs(v, base, root, inputs, depth + 1)
    elif isinstance(obj, str) and obj.lower().endswith(_INPUT_KEYS) and len(obj) < 500:
        for cand in (Path(obj), base / obj, root / obj):
            try:
                if cand.is_file():
                    inputs.setdefault(str(cand.resolve()), cand.resolve())
                    break
            except OSError:
                continue


def _rel(dest: Path, root: Path) -> Path:
    """``dest`` relative to the report in ``root``: a file outside the folder relative
    to where the folder ends up (:func:`arfem.scenarios.outdir.final_out_dir`), not to
    its staging directory."""
    dest, root = Path(dest).resolve(), Path(root).resolve()
    base = root if dest.is_relative_to(root) else final_out_dir(root)
    return Path(os.path.relpath(dest, base))


def _png_uri(p: Path) -> str | None:
    """A PNG file as a ``data:`` URI, or None if it is not a PNG or too large to embed."""
    if not p.is_file():
        return None
    data = p.read_bytes()
    if len(data) > MAX_EMBED or data[:8] != b"\x89PNG\r\n\x1a\n":
        return None
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def _markdown(text: str, base: Path, root: Path, embed: set | None = None) -> str:
    """Markdown (CommonMark with pipe tables, by markdown-it-py) as HTML.

    Raw HTML in the text is escaped, not passed through; a link is kept only where it
    points to a file that exists (made relative to the report), else its text stays.
    An image is embedded (``data:`` URI) when ``embed`` is given and the PNG exists (its
    name is then added to ``embed``); otherwise it becomes a link to the file, so that
    the page never depends on a file beside it.
    """
    md = MarkdownIt("commonmark", {"html": False}).enable("table")

    def image(renderer, tokens, idx, options, env):
        tok = tokens[idx]
        src = unquote(tok.attrGet("src") or "")
        alt = "".join(c.content for c in (tok.children or [])) or src
        dest = base / src
        uri = _png_uri(dest) if embed is not None and "://" not in src else None
        if uri:
            embed.add(Path(os.path.relpath(dest.resolve(), root.resolve())))
            return f'<img src="{uri}" alt="{_e(alt)}">'
        if "://" not in src and dest.is_file():
            return f'<a href="{_href(_rel(dest, root))}">{_e(alt)}</a>'
        return _e(alt)

    md.add_render_rule("image", image)

    def link_open(renderer, tokens, idx, options, env):
        href = tokens[idx].attrGet("href") or ""
        dest = base / unquote(href)
        if "://" not in href and not href.startswith("#") and dest.is_file():
            tokens[idx].attrSet("href", _href(_rel(dest, root)))
            return renderer.renderToken(tokens, idx, options, env)
        env["dropped_link"] = True
        return ""

    def link_close(renderer, tokens, idx, options, env):
        if env.pop("dropped_link", False):
            return ""
        return renderer.renderToken(tokens, idx, options, env)

    md.add_render_rule("link_open", link_open)
    md.add_render_rule("link_close", link_close)
    return md.render(text, {})


def _verdict(root: Path, shown: set) -> str:
    """The ``## Verdict`` section of the folder's Markdown (the first of README.md,
    summary.md and report.md that has one) as HTML, its figure embedded, for the top of the page:
    a reader meets the answer first and the machinery after it. The figures it shows are
    added to ``shown`` (the outputs below then link to them instead of repeating them).
    Empty if there is none."""
    for name in ("README.md", "summary.md", "report.md"):
        p = root / name
        if not p.is_file():
            continue
        lines = p.read_text("utf-8", errors="replace").splitlines()
        if "## Verdict" not in lines:
            continue
        i = lines.index("## Verdict") + 1
        j = next((k for k in range(i, len(lines)) if lines[k].startswith("## ")), len(lines))
        body = _markdown("\n".join(lines[i:j]), root, root, embed=shown)
        return (f'<section class="verdict" id="verdict"><h2>Verdict</h2>{body}</section>',
                name)
    return "", None


def _without_verdict(text: str) -> str:
    """``text`` (Markdown) without its ``## Verdict`` section, which the page shows at
    the top: a reader meets the verdict once."""
    lines = text.splitlines()
    if "## Verdict" not in lines:
        return text
    i = lines.index("## Verdict")
    j = next((k for k in range(i + 1, len(lines)) if lines[k].startswith("## ")), len(lines))
    note = ["## Verdict", "", "Shown at the top of this page.", ""]
    return "\n".join(lines[:i] + note + lines[j:])


def _scroll_tables(html: str) -> str:
    """Every table in a box that scrolls sideways by itself, so that a wide table never
    makes the page scroll at a laptop's or a phone's width."""
    return html.replace("<table", '<div class="wide"><table').replace(
        "</table>", "</table></div>")


def _anchor(rel: Path) -> str:
    return "f-" + "".join(c if c.isalnum() else "-" for c in rel.as_posix())


def _versions() -> list:
    from importlib import metadata
    rows = [("python", platform.python_version())]
    for name in _PACKAGES:
        try:
            rows.append((name, metadata.version(name)))
        except metadata.PackageNotFoundError:
            continue
    rows.append(("platform", f"{platform.system()} {platform.machine()}"))
    return rows


def _files(root: Path) -> list[Path]:
    """Every file under ``root`` (relative), hidden files and staging folders excluded."""
    out = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
        for f in sorted(filenames):
            if f.startswith(".") or f == REPORT_NAME:
                continue
            out.append((Path(dirpath) / f).relative_to(root))
    return out


def _title(root: Path, files: list[Path]) -> str:
    for name in ("README.md", "summary.md", "report.md"):
        p = root / name
        if p.is_file():
            for line in p.read_text("utf-8", errors="replace").splitlines():
                if line.startswith("# "):
                    return line[2:].strip().replace("`", "")
    return root.resolve().name


def write_html_report(out_dir, title: str | None = None, file_sizes: bool = True,
                      versions: bool = True) -> Path:
    """Write ``out_dir/report.html`` from whatever arfem outputs ``out_dir`` holds.

    Parameters
    ----------
    out_dir : str or Path
        An arfem output directory (any command), or its staging directory.
    title : str, optional
        Page title; default: the first heading of ``README.md`` / ``summary.md`` /
        ``report.md``, else the directory's name.
    file_sizes : bool
        List each file's size. ``arfem reproduce`` passes False: its report must be
        byte-identical on a rerun, and the size of the compressed field file depends
        on the last digits of the values, which depend on the CPU's BLAS kernels.
    versions : bool
        List the versions of the installed packages. ``arfem reproduce`` passes False:
        its report is committed, and a fresh clone must stay clean on a machine with
        other package versions (only arfem's own version is then given).

    Returns
    -------
    Path
        The report's path.

    Raises
    ------
    InputError
        If ``out_dir`` is not a directory.

    Examples
    --------
    >>> import tempfile, json
    >>> with tempfile.TemporaryDirectory() as d:
    ...     _ = Path(d, "summary.json").write_text(json.dumps({"rmse_um": 0.25}))
    ...     p = write_html_report(d)
    ...     text = p.read_text("utf-8")
    >>> "0.25" in text and "summary.json" in text
    True
    """
    root = Path(out_dir)
    if not root.is_dir():
        raise InputError("is not a directory", str(out_dir))
    files = _files(root)
    title = title or _title(root, files)
    by_dir: dict[Path, list[Path]] = {}
    for rel in files:
        by_dir.setdefault(rel.parent, []).append(rel)
    shown: set = set()
    lead, verdict_from = _verdict(root, shown)
    inputs: dict = {}
    sections = []
    toc = []
    for d in sorted(by_dir, key=lambda p: (len(p.parts), p.as_posix())):
        name = "outputs" if d == Path(".") else d.as_posix()
        body = _folder_body(root, d, by_dir[d], shown, inputs, verdict_from, title)
        if body:
            sid = "d-" + _anchor(d)
            toc.append(f'<li><a href="#{_e(sid)}">{_e(name)}</a></li>')
            sections.append(f'<h2 id="{_e(sid)}">{_e(name)}</h2>' + "".join(body))
    page = _page(title, lead, toc, sections, _external_inputs(inputs, root), root, files,
                 file_sizes, versions)
    path = root / REPORT_NAME
    atomic_write_text(path, _scroll_tables(page))
    return path


def _figure(root: Path, r: Path) -> str:
    """A PNG embedded as a ``data:`` URI with a link to its file; one too large (or not a
    PNG) only linked."""
    data = (root / r).read_bytes()
    if len(data) > MAX_EMBED or data[:8] != b"\x89PNG\r\n\x1a\n":
        return (f'<p><a href="{_href(r)}">{_e(r.as_posix())}</a> '
                f"({_size(len(data))}, linked)</p>")
    uri = "data:image/png;base64," + base64.b64encode(data).decode("ascii")
    return (f'<figure id="{_e(_anchor(r))}"><img src="{uri}" alt="{_e(r.name)}">'
            f'<figcaption><a href="{_href(r)}">{_e(r.as_posix())}</a>'
            "</figcaption></figure>")


def _folder_body(root: Path, d: Path, rels: list[Path], shown: set, inputs: dict,
                 verdict_from, title: str = "") -> list[str]:
    """The HTML blocks of one folder ``d`` of the output directory: its Markdown files
    first (the top folder's README open, the others collapsed), then its figures, JSON
    tables and TOML inputs; ``inputs`` collects the input files the JSON names."""
    name = "outputs" if d == Path(".") else d.as_posix()
    body = []
    # the top folder's README (else its first Markdown file) is the page's lead text,
    # open, its pictures in place and its title (the page's) not repeated; every other
    # Markdown file is collapsed
    mds = sorted((r for r in rels if r.suffix.lower() == ".md"),
                 key=lambda r: (r.name != "README.md", r.name))
    for k, r in enumerate(mds):
        text = (root / r).read_text("utf-8", errors="replace")
        if verdict_from is not None and r == Path(verdict_from):
            text = _without_verdict(text)
        _linked_inputs(text, (root / r).parent, root, inputs)
        lead = d == Path(".") and k == 0
        if lead:
            text = _without_title(text, title)
        body.append(f'<details{" open" if lead else ""}><summary><a href="{_href(r)}">'
                    f"{_e(r.as_posix())}</a></summary>"
                    f"{_markdown(text, (root / r).parent, root, shown if lead else None)}"
                    "</details>")
    pngs = [r for r in rels if r.suffix.lower() == ".png" and r not in shown]
    body += [f'<p class="note">{_e(r.as_posix())}: shown above '
             f'(<a href="{_href(r)}">file</a>).</p>' for r in rels if r in shown]
    jsons = [r for r in rels if r.suffix.lower() == ".json"]
    tomls = [r for r in rels if r.suffix.lower() == ".toml"]
    body += [_figure(root, r) for r in pngs]
    if len(jsons) > MAX_JSON_TABLES:
        body.append(f'<p class="note">{len(jsons)} JSON files in '
                    f"<code>{_e(name)}/</code> (listed under Files, not tabulated)</p>")
    else:
        for r in jsons:
            body.append(_json_section(root / r, r, inputs, root))
    for r in tomls:
        text = (root / r).read_text("utf-8", errors="replace")
        body.append(f'<h3>input: <a href="{_href(r)}">{_e(r.as_posix())}</a></h3>'
                    f"<pre>{_e(text)}</pre>")
    return body


def _linked_inputs(text: str, base: Path, root: Path, inputs: dict) -> None:
    """Record the files outside ``root`` that a Markdown file links (the model and the
    record a replay names): they are the folder's inputs."""
    for href in re.findall(r"\]\(([^)\s]+)\)", text):
        if "://" in href or href.startswith("#"):
            continue
        dest = (base / unquote(href)).resolve()
        if dest.is_file() and not dest.is_relative_to(root.resolve()):
            inputs.setdefault(str(dest), dest)


def _without_title(text: str, title: str) -> str:
    r"""``text`` (Markdown) without its first line when that is the page's title.

    >>> _without_title("# `run`: a unit\n\nbody", "run: a unit")
    '\nbody'
    """
    first, _, rest = text.partition("\n")
    return rest if first.startswith("# ") and \
        first[2:].strip().replace("`", "") == title else text


def _external_inputs(inputs: dict, root: Path) -> list[str]:
    """List items linking the inputs the JSON files name that live outside the
    directory, relative to the report."""
    ext = []
    for p in sorted(inputs.values()):
        if p.is_relative_to(root.resolve()):
            continue                                   # shown or listed with the outputs
        rel = _rel(p, root)
        ext.append(f'<li><a href="{_href(rel)}">{_e(rel.as_posix())}</a></li>')
    return ext


def _page(title: str, lead: str, toc: list[str], sections: list[str], ext: list[str],
          root: Path, files: list[Path], file_sizes: bool, versions: bool = True) -> str:
    """The whole page: title, verdict, contents, the folders' sections, the inputs, the
    file listing and the software versions."""
    listing = "".join(
        f'<tr><td><a href="{_href(r)}">{_e(r.as_posix())}</a></td>'
        + (f'<td class="num">{_e(_size((root / r).stat().st_size))}</td>' if file_sizes else "")
        + "</tr>" for r in files)
    rows = _versions() if versions else [r for r in _versions() if r[0] == "arfem"]
    software = "".join(f"<tr><th>{_e(k)}</th><td>{_e(v)}</td></tr>" for k, v in rows)
    said = ("Versions installed where this report was written." if versions else
            "The arfem version that wrote this report (the other packages' versions are "
            "left out: the page is committed and must not change with them).")
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{_e(title)}</title><style>{_CSS}</style></head><body>"
        f"<h1>{_e(title)}</h1>"
        + lead +
        f'<p class="note">Generated by <code>arfem report</code> from the files in this '
        "directory; the numbers are those of its JSON files, rounded to "
        f"{DIGITS} significant digits (the files have every digit), the figures are "
        "embedded, the links are relative.</p>"
        f'<ul>{"".join(toc)}<li><a href="#inputs">inputs</a></li>'
        '<li><a href="#files">files</a></li><li><a href="#versions">software</a></li></ul>'
        + "".join(sections)
        + '<h2 id="inputs">inputs</h2>'
        + (f"<ul>{''.join(ext)}</ul>" if ext else "")
        + ('<p class="note">The input files copied into this directory are shown above '
           "(<code>*.toml</code>).</p>" if any(r.suffix == ".toml" for r in files) else "")
        + ("" if ext or any(r.suffix == ".toml" for r in files) else
           '<p class="note">No input file is recorded in this directory.</p>')
        + '<h2 id="files">files</h2><table><tr><th>file</th>'
        + ("<th>size</th>" if file_sizes else "") + f"</tr>{listing}</table>"
        + f'<h2 id="versions">software</h2><p class="note">{said}</p>'
        f"<table>{software}</table>"
        "</body></html>\n")
