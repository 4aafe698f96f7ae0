"""``arfem report DIR``: the command's parser and printed line only; the page itself is
written by the library :func:`arfem.scenarios.html_report.write_html_report`, which
every command that writes an output directory calls."""
from __future__ import annotations

from arfem.scenarios.html_report import REPORT_NAME, write_html_report
from arfem.scenarios.outdir import replace_owned_file


def main(args) -> int:
    """``arfem report DIR``: only into a folder arfem wrote, never over a ``report.html``
    arfem did not write (``docs/safety.md``), and listed in the folder's ownership
    manifest with its current SHA-256, so that every later arfem command (a resumed sweep,
    a ``--force`` re-run) may replace it (:func:`arfem.scenarios.outdir.replace_owned_file`)."""
    p = replace_owned_file(args.dir, REPORT_NAME, lambda dst: write_html_report(dst.parent),
                           force=args.force)
    print(p)
    return 0


def add_parser(sub) -> None:
    p = sub.add_parser("report", help="write DIR/report.html: one self-contained page of an "
                                      "output directory",
                       description="Write a self-contained report.html (figures embedded, the "
                                   "JSON numbers as tables, inputs, software versions, links "
                                   "to the data files) into an arfem output directory. Only "
                                   "into a folder arfem wrote (its .arfem-outputs.json lists "
                                   "its files); a report.html arfem did not write is never "
                                   "replaced.")
    p.add_argument("dir", help="an output directory of arfem run, reproduce, diagnose, sweep "
                               "or allocate")
    p.add_argument("--force", action="store_true",
                   help="replace arfem's own report.html also if it was changed since")
    p.set_defaults(func=main)
