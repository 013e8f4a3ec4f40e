"""Siconos' text files of 2D frictional problems and LCPs (docs/design.md section 5b).

The layout is the one Siconos numerics prints and reads (``frictionContact_printInFile``,
``globalFrictionContact_newFromFile``, ``linearComplementarity_newFromFile``): whitespace-
separated numbers, and for each matrix a NumericsMatrix block:

* ``storage size0 size1`` then, for ``storage = 0`` (dense), ``size0 size1`` again and the
  ``size0 * size1`` entries in column-major order;
* ``storage = 1`` (sparse block): the number of blocks, the numbers of block rows and
  columns, their cumulative sizes, the block-row pointers and block-column indices, then per
  block its number and its entries (column-major);
* ``storage = 2`` (sparse): the origin (0 triplet, 1 CSC, 2 CSR), the line ``CSparse Version
  ...``, a header ``[triplet: |csr: ]M-by-N, nzmax: Z nnz: K[, 1-norm: X]`` and either
  ``col j : locations a to b`` lines each followed by ``i : x`` lines (``row`` for CSR) or
  ``i j : x`` triplet lines (a repeated triplet is summed, as CSparse does).

Files: ``fc2d`` (reduced): ``d nc W q mu``; ``gfc2d`` (global): ``d nc M H q b mu`` with
``M v = q + H r``, ``u = H^T v + b``; ``lcp``: ``n M q`` (anything after q is a comment).
Contacts are ``(N, T)`` pairs side by side in Siconos' order. Every fault is one InputError
naming the file and the field; nothing after the last field is read.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from qpbench.errors import InputError

KINDS = ("fc2d", "gfc2d", "lcp")
LARGEST_SIZE = 10_000_000  # rows, columns or entries of one matrix
LARGEST_DENSE = 50_000_000  # entries of a dense matrix
_HEADER = re.compile(r"^\s*(triplet:\s*|csr:\s*)?(\d+)-by-(\d+),\s*nzmax:\s*(\d+)\s+nnz:\s*(\d+)")
_SPAN = re.compile(r"^\s*(col|row)\s+(\d+)\s*:\s*locations\s+(-?\d+)\s+to\s+(-?\d+)\s*$")
_ENTRY = re.compile(r"^\s*(\d+)\s*:\s*(\S+)\s*$")
_TRIPLET = re.compile(r"^\s*(\d+)\s+(\d+)\s*:\s*(\S+)\s*$")


@dataclass
class LocalData:
    """A reduced problem as the file gives it (Siconos' per-contact order)."""

    W: sp.csc_matrix
    q: np.ndarray
    mu: np.ndarray


@dataclass
class GlobalData:
    """A global problem: ``M v = q + H r``, ``u = H^T v + b`` (per-contact order)."""

    M: sp.csc_matrix
    H: sp.csc_matrix
    q: np.ndarray
    b: np.ndarray
    mu: np.ndarray


@dataclass
class LcpData:
    M: np.ndarray
    q: np.ndarray


class _Cursor:
    """Reads a text file token by token (as fscanf does) or line by line (as fgets does),
    naming the file and the field in every error."""

    def __init__(self, file: str, text: str) -> None:
        self.file = file
        self.lines = text.splitlines()
        self.line = 0
        self.tokens: list[str] = self.lines[0].split() if self.lines else []
        self.position = 0

    def _advance(self) -> None:
        while self.position >= len(self.tokens) and self.line + 1 < len(self.lines):
            self.line += 1
            self.tokens, self.position = self.lines[self.line].split(), 0

    def token(self, field: str) -> str:
        self._advance()
        if self.position >= len(self.tokens):
            raise InputError(self.file, "the file ends before it", attribute=field)
        self.position += 1
        return self.tokens[self.position - 1]

    def integer(self, field: str, minimum: int = 0, maximum: int = LARGEST_SIZE) -> int:
        text = self.token(field)
        if not re.fullmatch(r"[+-]?\d{1,12}", text):
            raise InputError(self.file, f"expected an integer, got {text[:30]!r} (line "
                             f"{self.line + 1})", attribute=field)
        value = int(text)
        if not minimum <= value <= maximum:
            raise InputError(self.file, f"{value} is outside [{minimum}, {maximum:,}] (line "
                             f"{self.line + 1})", attribute=field)
        return value

    def numbers(self, field: str, count: int) -> np.ndarray:
        values = np.empty(count)
        for index in range(count):
            values[index] = _number(self, self.token(field), field)
        return values

    def next_line(self, field: str) -> str:
        """The next whole line (the rest of the current one must be empty)."""
        self._advance_line(field)
        return self.lines[self.line]

    def _advance_line(self, field: str) -> None:
        if self.position < len(self.tokens):
            raise InputError(self.file, f"unexpected {self.tokens[self.position][:30]!r} (line "
                             f"{self.line + 1})", attribute=field)
        if self.line + 1 >= len(self.lines):
            raise InputError(self.file, "the file ends before it", attribute=field)
        self.line += 1
        self.tokens, self.position = self.lines[self.line].split(), len(
            self.lines[self.line].split())


def _number(cursor: _Cursor, text: str, field: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise InputError(cursor.file, f"not a number: {text[:30]!r} (line {cursor.line + 1})",
                         attribute=field) from None
    if not np.isfinite(value):
        raise InputError(cursor.file, f"contains NaN or infinity (line {cursor.line + 1})",
                         attribute=field)
    return value


def read_matrix(cursor: _Cursor, field: str) -> sp.csc_matrix:
    """One NumericsMatrix block (module docstring) as a CSC matrix.

    Parameters
    ----------
    cursor : _Cursor
        The file being read, placed at the block's ``storage`` number.
    field : str
        The matrix's name (``W``, ``M``, ``H``), which starts the field named in an error.

    Returns
    -------
    sp.csc_matrix
        The matrix, ``size0 x size1``.

    Raises
    ------
    InputError
        When the block is malformed, too large or has an entry that is not a finite number.
    """
    storage = cursor.integer(f"{field}.storage", 0, 2)
    rows = cursor.integer(f"{field}.size0")
    cols = cursor.integer(f"{field}.size1")
    if storage == 0:
        again = (cursor.integer(f"{field}.size0"), cursor.integer(f"{field}.size1"))
        if again != (rows, cols):
            raise InputError(cursor.file, f"dense sizes {again} differ from ({rows}, {cols})",
                             attribute=f"{field}.size")
        if rows * cols > LARGEST_DENSE:
            raise InputError(cursor.file, f"{rows} x {cols} is too large for a dense matrix",
                             attribute=field)
        values = cursor.numbers(f"{field}.entries", rows * cols)
        return sp.csc_matrix(values.reshape(cols, rows).T)
    if storage == 1:
        return _read_block_matrix(cursor, field, rows, cols)
    return _read_csparse(cursor, field, rows, cols)


def _read_block_matrix(cursor: _Cursor, field: str, rows: int, cols: int) -> sp.csc_matrix:
    count = cursor.integer(f"{field}.nbblocks")
    if count == 0:
        return sp.csc_matrix((rows, cols))
    block_rows = cursor.integer(f"{field}.blocknumber0")
    block_cols = cursor.integer(f"{field}.blocknumber1")
    row_ends = [cursor.integer(f"{field}.blocksize0", 1, rows) for _ in range(block_rows)]
    col_ends = [cursor.integer(f"{field}.blocksize1", 1, cols) for _ in range(block_cols)]
    row_starts, col_starts = [0, *row_ends[:-1]], [0, *col_ends[:-1]]
    for label, ends, size in (("blocksize0", row_ends, rows), ("blocksize1", col_ends, cols)):
        if any(b <= a for a, b in zip([0, *ends[:-1]], ends, strict=True)) or ends[-1] != size:
            raise InputError(cursor.file, f"cumulative sizes {ends[:8]} do not rise to {size}",
                             attribute=f"{field}.{label}")
    filled1 = cursor.integer(f"{field}.filled1")
    filled2 = cursor.integer(f"{field}.filled2")
    if filled1 != block_rows + 1 or filled2 != count:
        raise InputError(cursor.file, f"filled1 {filled1} / filled2 {filled2} do not match "
                         f"{block_rows} block rows and {count} blocks", attribute=f"{field}.filled")
    pointers = [cursor.integer(f"{field}.index1_data", 0, count) for _ in range(filled1)]
    columns = [cursor.integer(f"{field}.index2_data", 0, block_cols - 1) for _ in range(filled2)]
    if pointers[0] != 0 or pointers[-1] != count or np.any(np.diff(pointers) < 0):
        raise InputError(cursor.file, "block-row pointers must rise from 0 to the number of "
                         "blocks", attribute=f"{field}.index1_data")
    dense = np.zeros((rows, cols))
    for block_row in range(block_rows):
        for number in range(pointers[block_row], pointers[block_row + 1]):
            label = cursor.integer(f"{field}.block", 0, count - 1)
            if label != number:
                raise InputError(cursor.file, f"block {label} where block {number} is due",
                                 attribute=f"{field}.block")
            column = columns[number]
            r0, r1 = row_starts[block_row], row_ends[block_row]
            c0, c1 = col_starts[column], col_ends[column]
            values = cursor.numbers(f"{field}.block[{number}]", (r1 - r0) * (c1 - c0))
            dense[r0:r1, c0:c1] = values.reshape(c1 - c0, r1 - r0).T
    return sp.csc_matrix(dense)


def _read_csparse(cursor: _Cursor, field: str, rows: int, cols: int) -> sp.csc_matrix:
    cursor.integer(f"{field}.origin", 0, 3)  # the format of the header line tells it too
    if not cursor.next_line(f"{field}.version").lstrip().startswith("CSparse"):
        raise InputError(cursor.file, f"expected a 'CSparse Version' line (line "
                         f"{cursor.line + 1})", attribute=f"{field}.version")
    header = cursor.next_line(f"{field}.header")
    match = _HEADER.match(header)
    if match is None:
        raise InputError(cursor.file, f"expected 'M-by-N, nzmax: Z nnz: K' (line "
                         f"{cursor.line + 1})", attribute=f"{field}.header")
    kind = (match.group(1) or "csc").strip().rstrip(":")
    m, n, nzmax, nnz = (int(match.group(k)) for k in range(2, 6))
    if (m, n) != (rows, cols):
        raise InputError(cursor.file, f"{m}-by-{n} differs from the sizes {rows} x {cols}",
                         attribute=f"{field}.header")
    if max(nzmax, nnz) > LARGEST_SIZE or nnz > nzmax:
        raise InputError(cursor.file, f"nnz {nnz} / nzmax {nzmax} out of range",
                         attribute=f"{field}.header")
    if kind == "triplet":
        row_index, col_index, values = np.empty(nnz, int), np.empty(nnz, int), np.empty(nnz)
        for k in range(nnz):
            line = cursor.next_line(f"{field}.entries")
            entry = _TRIPLET.match(line)
            if entry is None:
                raise InputError(cursor.file, f"expected 'i j : x' (line {cursor.line + 1})",
                                 attribute=f"{field}.entries")
            row_index[k], col_index[k] = int(entry.group(1)), int(entry.group(2))
            values[k] = _number(cursor, entry.group(3), f"{field}.entries")
        _check_indices(cursor, field, row_index, rows, col_index, cols)
        return sp.csc_matrix(sp.coo_matrix((values, (row_index, col_index)), shape=(m, n)))
    outer, inner = (n, m) if kind == "csc" else (m, n)
    word = "col" if kind == "csc" else "row"
    pointer, indices, values = np.zeros(outer + 1, int), [], []
    for j in range(outer):
        span = _SPAN.match(cursor.next_line(f"{field}.{word}"))
        if span is None or span.group(1) != word or int(span.group(2)) != j:
            raise InputError(cursor.file, f"expected '{word} {j} : locations a to b' (line "
                             f"{cursor.line + 1})", attribute=f"{field}.{word}")
        start, end = int(span.group(3)), int(span.group(4)) + 1
        if start != pointer[j] or end < start or end > nnz:
            raise InputError(cursor.file, f"{word} {j}: locations {start} to {end - 1} do not "
                             f"follow on from {pointer[j]} within nnz {nnz}",
                             attribute=f"{field}.{word}")
        pointer[j + 1] = end
        for _ in range(end - start):
            entry = _ENTRY.match(cursor.next_line(f"{field}.entries"))
            if entry is None:
                raise InputError(cursor.file, f"expected 'i : x' (line {cursor.line + 1})",
                                 attribute=f"{field}.entries")
            indices.append(int(entry.group(1)))
            values.append(_number(cursor, entry.group(2), f"{field}.entries"))
    if pointer[-1] != nnz:
        raise InputError(cursor.file, f"{pointer[-1]} entries where nnz says {nnz}",
                         attribute=f"{field}.header")
    index = np.asarray(indices, dtype=int)
    if np.any(index >= inner):
        raise InputError(cursor.file, f"an index is outside {inner}",
                         attribute=f"{field}.entries")
    compressed = (sp.csc_matrix if kind == "csc" else sp.csr_matrix)(
        (np.asarray(values, dtype=float), index, pointer), shape=(m, n))
    compressed.sum_duplicates()
    return sp.csc_matrix(compressed)


def _check_indices(cursor: _Cursor, field: str, rows: np.ndarray, m: int, cols: np.ndarray,
                   n: int) -> None:
    if np.any(rows >= m) or np.any(cols >= n):
        raise InputError(cursor.file, f"an index is outside {m} x {n}",
                         attribute=f"{field}.entries")


def _read_text(path: str | Path) -> _Cursor:
    file = str(path)
    try:
        text = Path(path).read_text()
    except FileNotFoundError:
        raise InputError(file, "no such file") from None
    except IsADirectoryError:
        raise InputError(file, "is a folder, not a Siconos file") from None
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(file, f"cannot read as text ({error})") from error
    return _Cursor(file, text)


def kind_of_file(path: str | Path) -> str:
    """``fc2d``, ``gfc2d`` or ``lcp`` from the file name as Siconos' test data names them.

    The names are ``fc2d_*``/``FC2D_*``, ``gfc2d_*`` and ``lcp_*``; InputError when the name
    says none.

    Parameters
    ----------
    path : str or Path
        The file; only its name is read.

    Returns
    -------
    str
        The kind, one of :data:`KINDS`.

    Raises
    ------
    InputError
        When the name starts with none of the kinds.
    """
    stem = Path(path).name.lower()
    for kind in ("gfc2d", "fc2d", "lcp"):
        if stem.startswith(kind):
            return kind
    raise InputError(str(path), "cannot tell the problem kind from the name (fc2d_*, gfc2d_*, "
                     "lcp_*); say it with --kind")


def _dimension(cursor: _Cursor) -> tuple[int, int]:
    dimension = cursor.integer("dimension", 1, 3)
    if dimension != 2:
        raise InputError(cursor.file, f"is {dimension}; qpbench reads 2D problems only",
                         attribute="dimension")
    return dimension, cursor.integer("numberOfContacts")


def read_local(path: str | Path) -> LocalData:
    """An ``fc2d`` file: W (2nc square), q (2nc), mu (nc).

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    LocalData
        W, q and mu in Siconos' per-contact order.

    Raises
    ------
    InputError
        When the file cannot be read, is not 2D or has a malformed or misfitting field.
    """
    cursor = _read_text(path)
    dimension, contacts = _dimension(cursor)
    W = read_matrix(cursor, "W")
    if W.shape[0] != W.shape[1]:
        raise InputError(cursor.file, f"must be square, got {W.shape[0]} x {W.shape[1]}",
                         attribute="W")
    if W.shape[0] != dimension * contacts:
        raise InputError(cursor.file, f"size {W.shape[0]} is not {dimension} x {contacts} "
                         "contacts", attribute="W")
    return LocalData(W, cursor.numbers("q", W.shape[0]), cursor.numbers("mu", contacts))


def read_global(path: str | Path) -> GlobalData:
    """A ``gfc2d`` file: M (dofs square), H (dofs x 2nc), q (dofs), b (2nc), mu (nc).

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    GlobalData
        M, H, q, b and mu in Siconos' per-contact order.

    Raises
    ------
    InputError
        When the file cannot be read, is not 2D or has a malformed or misfitting field.
    """
    cursor = _read_text(path)
    dimension, contacts = _dimension(cursor)
    M = read_matrix(cursor, "M")
    if M.shape[0] != M.shape[1]:
        raise InputError(cursor.file, f"must be square, got {M.shape[0]} x {M.shape[1]}",
                         attribute="M")
    H = read_matrix(cursor, "H")
    if H.shape != (M.shape[0], dimension * contacts):
        raise InputError(cursor.file, f"is {H.shape[0]} x {H.shape[1]}, expected "
                         f"{M.shape[0]} x {dimension * contacts}", attribute="H")
    q = cursor.numbers("q", M.shape[0])
    b = cursor.numbers("b", H.shape[1])
    return GlobalData(M, H, q, b, cursor.numbers("mu", contacts))


def read_lcp(path: str | Path) -> LcpData:
    """An ``lcp`` file: n, M (n x n), q (n).

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    LcpData
        M as a dense array and q.

    Raises
    ------
    InputError
        When the file cannot be read or has a malformed or misfitting field.
    """
    cursor = _read_text(path)
    size = cursor.integer("size")
    M = read_matrix(cursor, "M")
    if M.shape != (size, size):
        raise InputError(cursor.file, f"is {M.shape[0]} x {M.shape[1]}, expected {size} x "
                         f"{size}", attribute="M")
    return LcpData(M.toarray(), cursor.numbers("q", size))
