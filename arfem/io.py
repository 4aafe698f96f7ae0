"""Ground-layer file plumbing: strict reading of a user's text files (one-line errors)
and atomic writes (a reader never sees a half-written file).

Everything in arfem reads and writes files through here; this module imports nothing of
arfem but :mod:`arfem.params` (for :class:`~arfem.params.InputError`).
"""
from __future__ import annotations

import contextlib
import csv
import hashlib
import io as _io
import json
import math
import os
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from arfem.limits import Limits, resolve
from arfem.params import InputError

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["sha256_file", "toml_has_table", "read_text_utf8", "read_toml", "json_text", "atomic_write_text",
           "atomic_write_bytes", "atomic_path", "write_json", "write_csv", "files_read",
           "MAX_TEXT_BYTES", "TomlFile", "read_toml_file", "CsvTable", "read_csv_table"]

#: Largest user text file (TOML, CSV) read whole [bytes]: 1 GiB would take minutes and
#: ~10x its size in memory to parse; far above any record here (lifted by --allow-large).
MAX_TEXT_BYTES = 256 * 1024 ** 2

#: Every user file read in this process (absolute paths): the inputs that
#: ``scenarios/outdir.py`` never lets an output replace.
_FILES_READ: set = set()


def _open_input(path: Path):
    """Open a user's file for reading (binary): the one place every input is opened, so
    that a test can count how often a command reads each one."""
    return open(path, "rb")


def files_read() -> frozenset:
    """Absolute paths of every file read through :func:`read_text_utf8` so far."""
    return frozenset(_FILES_READ)


def read_text_utf8(path: str | os.PathLike, missing: str = "file not found",
                   max_bytes: int | None = None, record: bool = True,
                   limits: Limits | None = None) -> str:
    """The text of a UTF-8 file (a leading BOM dropped).

    A missing file, a directory, an unreadable file, a file larger than ``max_bytes``
    [bytes] (default :data:`MAX_TEXT_BYTES`; unless ``limits.large``, see
    :class:`arfem.limits.Limits`), a NUL byte (checked in the first 64 KiB
    before the rest is read) or bytes that are not UTF-8 raise :class:`InputError`
    naming the file (and, for bad bytes, the line).

    With ``record`` (the default) the file counts as an input of this process: no
    output staged by ``scenarios/outdir.py`` may replace it (see :func:`files_read`).
    Pass ``record=False`` to read an earlier output only to compare it.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "x.csv"
    >>> _ = p.write_bytes(b"a,b\\n1,\\xe9\\n")
    >>> try:
    ...     read_text_utf8(p)
    ... except InputError as e:
    ...     print(str(e).replace(str(p), "x.csv"))
    x.csv: line 2: is not UTF-8 (byte 6 of the file)
    """
    p = Path(path)
    max_bytes = MAX_TEXT_BYTES if max_bytes is None else max_bytes
    NUL = b"\0"
    try:
        if not p.is_file():
            raise InputError(missing if not p.exists() else "is not a file", str(p))
        if record:
            _FILES_READ.add(os.path.abspath(p))
        size = p.stat().st_size
        if size > max_bytes and not resolve(limits).large:
            raise InputError(f"is {size / 1024 ** 2:.0f} MiB; arfem reads at most "
                             f"{max_bytes / 1024 ** 2:.0f} MiB (pass --allow-large to lift "
                             "the limit)", str(p))
        with _open_input(p) as fh:
            head = fh.read(1 << 16)
            if b"\0" in head:
                raise InputError(f"holds a NUL byte (byte {head.index(NUL)} of the file): "
                                 "a binary file, not text", str(p))
            raw = head + fh.read()
    except OSError as e:
        raise InputError(f"cannot be read ({e.strerror or e})", str(p)) from None
    if b"\0" in raw:
        raise InputError(f"holds a NUL byte (byte {raw.index(NUL)} of the file): "
                         "a binary file, not text", str(p))
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = raw[:e.start].count(b"\n") + 1
        raise InputError(f"is not UTF-8 (byte {e.start} of the file)",
                         f"{p}: line {line}") from None


def read_toml(path: str | os.PathLike, limits: Limits | None = None) -> dict:
    """Parse a UTF-8 TOML file; anything wrong is one :class:`InputError` line."""
    return read_toml_file(path, limits).data


@dataclass(frozen=True)
class TomlFile:
    """A TOML file read once: its path, its text (for a copy that keeps the comments)
    and the parsed document, passed along so that no command reads it again."""

    path: Path
    text: str
    data: dict

    def has_table(self, name: str) -> bool:
        """True when the document has a table ``name``."""
        return isinstance(self.data.get(name), dict)


def read_toml_file(path: str | os.PathLike, limits: Limits | None = None) -> TomlFile:
    """Read and parse a UTF-8 TOML file once (:class:`TomlFile`); anything wrong is one
    :class:`InputError` line."""
    text = read_text_utf8(path, limits=limits)
    return TomlFile(Path(path), text, _parse_toml(text, path))


def _parse_toml(text: str, path) -> dict:
    """The document of TOML ``text`` read from ``path`` (named in a refusal)."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"malformed TOML: {str(e).splitlines()[0]}", str(path)) from None
    except RecursionError:
        raise InputError("malformed TOML: nested too deeply", str(path)) from None
    except ValueError as e:             # e.g. an integer of more than 4300 digits
        raise InputError(f"malformed TOML: {str(e).splitlines()[0]}", str(path)) from None


def toml_has_table(path: str | os.PathLike, table: str) -> bool:
    """True when ``path`` is a ``.toml`` file with a line opening ``[table]`` (a cheap
    text test that decides which reader a file goes to, before the strict one runs)."""
    p = Path(path)
    if p.suffix != ".toml" or not p.is_file():
        return False
    try:
        with _open_input(p) as fh:
            text = fh.read().decode("utf-8", errors="replace")
    except OSError:
        return False
    return any(line.strip().startswith(f"[{table}]") for line in text.splitlines())


def sha256_file(path: str | os.PathLike) -> str:
    """SHA-256 (hex) of a file's bytes, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _umask() -> int:
    m = os.umask(0o022)
    os.umask(m)
    return m


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        if os.path.exists(tmp):           # mkstemp's 0600 -> what open() would have made
            os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def _jsonable(o):
    if isinstance(o, dict):
        return {str(k): _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, np.ndarray):
        return [_jsonable(v) for v in o.tolist()]
    if isinstance(o, (np.floating, float)):
        f = float(o)
        return f if math.isfinite(f) else None
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.bool_,)):
        return bool(o)
    return o


def json_text(obj, indent: int | None = None) -> str:
    """JSON text of ``obj`` with numpy types converted and NaN/inf as null.

    >>> json_text({"ratio": np.float64(1.25), 3000.0: [np.int64(2), float("nan")]})
    '{"ratio": 1.25, "3000.0": [2, null]}'
    """
    return json.dumps(_jsonable(obj), indent=indent, allow_nan=False, ensure_ascii=False)


def write_json(path: str | os.PathLike, obj) -> None:
    """Atomic JSON (NaN/inf written as null, numpy types converted)."""
    atomic_write_text(path, json_text(obj, indent=2) + "\n")


def write_csv(path: str | os.PathLike, columns: dict[str, np.ndarray], fmt: str = "%.10g") -> None:
    """Atomic CSV from named equal-length columns (header = the names)."""
    names = list(columns)
    data = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
    import io as _io
    buf = _io.StringIO()
    np.savetxt(buf, data, delimiter=",", header=",".join(names), comments="", fmt=fmt)
    atomic_write_text(path, buf.getvalue())


# -- the one CSV reader of a measured record ---------------------------------------------

#: A number as the measured-data contract writes it: ASCII digits, '.' decimal mark.
_NUMBER_RE = re.compile(r"^[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?$")
_NONFINITE_RE = re.compile(r"^[+-]?(?:nan|inf|infinity)$", re.IGNORECASE)


@dataclass(frozen=True)
class CsvTable:
    """A record's CSV read once, strictly (:func:`read_csv_table`).

    Attributes
    ----------
    path : Path
    header : tuple of str
        The column names (stripped, each once), in file order.
    header_line : int
        The CSV line of the header.
    numbers : dict
        Column name -> float ndarray (NaN for an empty cell) for every column read as
        numbers; each finite where given.
    cells : dict
        Column name -> object ndarray of the raw cells of every other column.
    lines : ndarray of int
        The CSV line of each data row (blank lines skipped).
    echo : bool
        False where the file's cells must never be shown (outside the record's folder).
    """

    path: Path
    header: tuple
    header_line: int
    numbers: dict
    cells: dict
    lines: np.ndarray
    echo: bool = True


def read_csv_table(path: str | os.PathLike, numeric: Callable[[str], bool], *,
                   max_bytes: int, max_rows: int, limits: Limits | None = None,
                   missing: str = "CSV file not found", echo: bool = True,
                   label: Callable[[str], str] | None = None) -> CsvTable:
    """Read a record's CSV (one header row, ',' separated, '.' decimals, UTF-8) once,
    with every limit of docs/safety.md, before anything is parsed: at most
    ``max_bytes`` [bytes] and ``max_rows`` data rows (a line count) unless
    ``limits.large`` (``--allow-large``), no NUL byte, UTF-8. Then strictly: every
    header name non-empty and given once, every row as many fields as the header, and
    in each column ``numeric(name)`` names a number or an empty cell in every row (NaN,
    inf, text, digits other than ASCII and overflows refused, naming the line and
    column -- ``label(name)``, default ``repr(name)`` -- and a cell's content only
    with ``echo``).

    A file without a quote character is parsed by pandas' C reader (a 647 000-row
    record in about a second); any doubt (a quote, a field count, a cell pandas cannot
    take as a number, an infinity) sends it to the strict line-by-line reader, which
    gives the same numbers or the refusal naming the cell.

    Raises
    ------
    InputError
        One line naming the file, the line and column, and what is wrong.
    """
    p = Path(path)
    lim = resolve(limits)
    text = read_text_utf8(p, missing=missing, max_bytes=max_bytes, limits=lim)
    n_rows = text.count("\n") - 1                 # minus the header
    if n_rows > max_rows and not lim.large:
        raise InputError(f"has about {n_rows:,} rows; arfem reads at most {max_rows:,} rows "
                         "of a record (resample the record, or pass --allow-large)", str(p))
    table = _fast_csv(p, text, numeric, echo) if '"' not in text else None
    return table if table is not None else _strict_csv(p, text, numeric, echo,
                                                       label or repr)


#: Up to this many rows, a table of plain numbers is parsed by numpy (no pandas import,
#: ~0.2 s, for a record of a day); above it pandas' C parser is the faster.
PLAIN_NUMBERS_MAX_ROWS = 100_000
#: The characters of a table of plain decimal numbers: a data part with any other (a
#: space, nan, inf, a letter, a quote) is left to pandas and the strict reader.
_NOT_PLAIN = str.maketrans("", "", "0123456789eE+-.,\r\n")


def _plain_numbers(lines, filled, header, numeric) -> tuple | None:
    """(numbers, cells) of a table whose every cell is a plain number, parsed by numpy
    (correctly rounded, as the strict reader's float()); a column not read as numbers
    keeps its cells' text. None where a cell is not a plain number or the table is
    large (pandas then reads it)."""
    body = filled[1:]
    if len(body) > PLAIN_NUMBERS_MAX_ROWS:
        return None
    rows = [lines[i].rstrip("\r") for i in body]
    if "".join(rows).translate(_NOT_PLAIN):
        return None
    try:                              # a blank cell or a malformed number: not plain
        a = np.loadtxt(rows, delimiter=",", dtype=float, ndmin=2)
    except ValueError:
        return None
    if a.shape != (len(body), len(header)) or not np.isfinite(a).all():
        return None
    numbers = {c: np.ascontiguousarray(a[:, j]) for j, c in enumerate(header) if numeric(c)}
    text = [j for j, c in enumerate(header) if not numeric(c)]
    split = [r.split(",") for r in rows] if text else []
    return numbers, {header[j]: np.array([r[j] for r in split], dtype=object) for j in text}


def _fast_csv(p: Path, text: str, numeric, echo: bool) -> CsvTable | None:
    """The table by a C parser where the text holds no quote (numpy's for a table of
    plain numbers up to :data:`PLAIN_NUMBERS_MAX_ROWS` rows, else pandas'), or None
    where any check fails (the strict reader then finds and names the fault)."""
    lines = text.split("\n")
    filled = [i for i, ln in enumerate(lines) if ln.strip()]
    if len(filled) < 2:
        return None
    h = filled[0]
    header = [c.strip() for c in lines[h].split(",")]
    commas = len(header) - 1
    if (len(set(header)) != len(header) or not all(header)
            or any(lines[i].count(",") != commas for i in filled[1:])):
        return None
    plain = _plain_numbers(lines, filled, header, numeric)
    if plain is not None:
        return CsvTable(p, tuple(header), h + 1, *plain,
                        np.asarray(filled[1:], dtype=int) + 1, echo)
    import pandas as pd
    try:
        df = pd.read_csv(_io.StringIO(text), header=None, names=header, skiprows=h + 1,
                         dtype={c: (float if numeric(c) else str) for c in header},
                         keep_default_na=False, na_values={c: [""] for c in header
                                                           if numeric(c)},
                         index_col=False, skip_blank_lines=True, engine="c")
    except (ValueError, TypeError, OverflowError, pd.errors.ParserError):
        return None
    if len(df) != len(filled) - 1:
        return None
    numbers = {c: df[c].to_numpy(dtype=float) for c in header if numeric(c)}
    if any(np.isinf(v).any() for v in numbers.values()):
        return None
    cells = {c: df[c].to_numpy(dtype=object) for c in header if not numeric(c)}
    return CsvTable(p, tuple(header), h + 1, numbers, cells,
                    np.asarray(filled[1:], dtype=int) + 1, echo)


def _strict_csv(p: Path, text: str, numeric, echo: bool, label) -> CsvTable:
    """The table by the csv module, row by row: the refusal names the first fault."""
    header, header_line, rows, lines = _csv_rows(p, text)
    numbers, cells = {}, {}
    for j, name in enumerate(header):
        if numeric(name):
            numbers[name] = _number_column(p, rows, lines, j, label(name), echo)
        else:
            cells[name] = np.array([row[j] for row in rows], dtype=object)
    return CsvTable(p, tuple(header), header_line, numbers, cells,
                    np.asarray(lines, dtype=int), echo)


def _csv_rows(p: Path, text: str):
    """(header, its line, rows, each row's line) of a strict, rectangular CSV."""
    reader = csv.reader(_io.StringIO(text, newline=""), strict=True)
    rows, lines, header, header_line, start = [], [], None, 0, 1
    try:
        while True:
            start = reader.line_num + 1           # where the next record begins
            try:
                row = next(reader)
            except StopIteration:
                break
            if not row or (len(row) == 1 and not row[0].strip()):
                continue          # blank line
            if header is None:
                header, header_line = [c.strip() for c in row], reader.line_num
                continue
            if len(row) != len(header):
                raise InputError(f"has {len(row)} fields, the header has {len(header)}",
                                 f"{p}: line {reader.line_num}")
            rows.append(row)
            lines.append(reader.line_num)
    except csv.Error as e:
        if reader.line_num > start:               # e.g. a quote never closed
            raise InputError(f"broken CSV: {e} (the record starting here runs on to line "
                             f"{reader.line_num}: a quote opened here is never closed?)",
                             f"{p}: line {start}") from None
        raise InputError(f"broken CSV: {e}", f"{p}: line {reader.line_num}") from None
    if header is None:
        raise InputError("is empty (no header row)", str(p))
    for i, name in enumerate(header):
        if not name:
            raise InputError(f"header field {i + 1} is empty", f"{p}: line {header_line}")
        if header.index(name) != i:
            raise InputError(f"column {name!r} appears twice in the header",
                             f"{p}: line {header_line}")
    if not rows:
        raise InputError("has a header but no data rows", str(p))
    return header, header_line, rows, lines


def _number_column(p: Path, rows, lines, j: int, label: str, echo: bool) -> np.ndarray:
    """Numbers of column ``j``; empty cells -> NaN; text, NaN, inf or an overflow -> one
    line naming the line and column (the cell shown only with ``echo``)."""
    out = np.empty(len(rows))
    match = _NUMBER_RE.match
    where = f"column {label}"
    for i, row in enumerate(rows):
        cell = row[j].strip()
        if not cell:
            out[i] = np.nan
            continue
        if match(cell):
            out[i] = float(cell)
            if not math.isinf(out[i]):
                continue
            shown = repr(cell if len(cell) <= 40 else cell[:40] + "…") if echo else "the cell"
            raise InputError(f"{shown} overflows to infinity", f"{p}: line {lines[i]}, {where}")
        # only a bad cell is shown (a repr per cell was a tenth of a real record's run)
        shown = repr(cell if len(cell) <= 40 else cell[:40] + "…") if echo else "the cell"
        if _NONFINITE_RE.match(cell):
            raise InputError(f"{shown} is not a finite number (NaN/inf are refused; leave the "
                             "cell empty for a missing value)", f"{p}: line {lines[i]}, {where}")
        raise InputError(f"{shown} is not a number", f"{p}: line {lines[i]}, {where}")
    return out
