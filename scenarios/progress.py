"""Progress lines on stderr for commands with slow steps (tqdm).

A :class:`Progress` is a callable ``progress(step_name)``: call it when a step starts.
It shows one line on stderr, rewritten in place: the command, steps done / steps
planned, the step under way and the elapsed time. It is silent when disabled
(``--no-progress``) or when stderr is not a terminal (a log file, CI, a pipe), so
outputs and logs stay clean.

Engines take a plain ``progress: Callable[[str], None] | None`` argument and call it
with a step name where a slow step starts; they need not import this module (the
pure ``models/`` layer must not print): the command builds a :class:`Progress` and
passes it down.

Examples
--------
>>> import io
>>> buf = io.StringIO()
>>> with Progress(3, "arfem run", file=buf, tty=True) as progress:
...     progress("FEM solve")
...     progress("figure")
>>> "figure" in buf.getvalue()
True
>>> with Progress(3, "arfem run", file=io.StringIO(), tty=False) as progress:
...     progress("FEM solve")          # not a terminal: nothing is written
"""
from __future__ import annotations

import sys

__all__ = ["Progress", "tagged", "add_progress_flag"]


def _columns() -> int:
    """Terminal width, or 120 where the terminal reports none (a pty of width 0)."""
    import shutil
    cols = shutil.get_terminal_size((120, 24)).columns
    return cols if cols >= 40 else 120


class Progress:
    """A step counter on stderr; call it with the name of each step as it starts.

    Parameters
    ----------
    total : int
        Steps planned (grows if more are started).
    desc : str
        What is running, e.g. ``"arfem run"``.
    enabled : bool
        False: write nothing (``--no-progress``).
    file : file object, optional
        Where to write; default ``sys.stderr``.
    tty : bool, optional
        Whether ``file`` is a terminal; default ``file.isatty()``.
    """

    def __init__(self, total: int, desc: str, enabled: bool = True, file=None,
                 tty: bool | None = None):
        from tqdm.auto import tqdm
        file = sys.stderr if file is None else file
        if tty is None:
            try:
                tty = bool(file.isatty())
            except (AttributeError, ValueError):
                tty = False
        self.enabled = bool(enabled) and tty
        self.desc = desc
        self._bar = tqdm(total=max(int(total), 1), desc=desc, file=file,
                         disable=not self.enabled, leave=True, ncols=_columns(),
                         mininterval=0.0, bar_format="{desc} [{elapsed} elapsed]")
        self._started = False
        self._stop = None
        if self.enabled:
            # keep the elapsed time ticking through a long step, so the line shows it is alive
            import threading
            self._stop = threading.Event()
            threading.Thread(target=self._tick, daemon=True).start()

    def _tick(self) -> None:
        while not self._stop.wait(1.0):
            try:
                self._bar.refresh()
            except Exception:            # pragma: no cover - a closed stream: stop ticking
                return

    def _show(self, what: str) -> None:
        self._bar.set_description_str(
            f"{self.desc}: {what} ({self._bar.n}/{self._bar.total} steps done)", refresh=True)

    def __call__(self, step: str) -> None:
        if not self.enabled:
            return
        if self._started:
            self._bar.update(1)
        self._started = True
        if self._bar.n >= self._bar.total:
            self._bar.total = self._bar.n + 1
        self._show(str(step))

    def close(self) -> None:
        if self._stop is not None:
            self._stop.set()
        if self.enabled and self._started:
            self._bar.update(1)
            self._bar.total = self._bar.n
            self._show("done")
        self._bar.close()

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def tagged(progress, prefix: str):
    """A progress hook that prefixes every step with ``prefix`` (one item of several).

    >>> seen = []
    >>> tagged(seen.append, "ch1")("fit")
    >>> seen
    ['ch1: fit']
    """
    return lambda step: progress(f"{prefix}: {step}")


def add_progress_flag(parser) -> None:
    """Add ``--no-progress`` to an argparse (sub)parser."""
    parser.add_argument("--no-progress", action="store_true",
                        help="no progress line on stderr (it is also off when stderr is not "
                             "a terminal)")
