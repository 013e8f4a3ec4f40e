"""Siconos' solvers behind a pipe: runs under the system interpreter (/usr/bin/python3).

Debian's ``python3-siconos`` is built for the system Python and its numpy, so it cannot be
imported in qpbench's virtual environment. This program imports only the standard library,
numpy and ``siconos.numerics`` (never qpbench), and answers solve requests on stdin/stdout
until stdin closes. ``--probe`` prints one JSON object instead (Siconos' version and which
of the asked solvers this build lacks) and exits.

Messages, both ways: one JSON line (the header), then the raw bytes of the arrays the header
lists as ``[name, dtype, shape]``, in that order (little-endian, C order).

* Request: ``problem`` (``lcp``: arrays ``data``, ``indices``, ``indptr`` of the CSC matrix Q
  and ``q``; ``fc2d``: the same for W in qpbench's layout ``r = (l_N, l_T)``, ``q`` and
  ``mu``), ``solver`` (the name of a Siconos solver id, e.g. ``SICONOS_LCP_LEMKE``),
  ``iparam`` and ``dparam`` (``{index: value}`` set on the solver options).
* Answer: ``info`` (the driver's return value), ``iterations``
  (``iparam[SICONOS_IPARAM_ITER_DONE]``), ``residual`` (``dparam[SICONOS_DPARAM_RESIDU]``),
  ``time_s``, ``setup_time_s``, ``solve_time_s``, ``error`` (an exception's text, or null)
  and the array ``l`` (qpbench's order).

``time_s`` is measured here across qpbench's one timing boundary (docs/design.md section 7):
from the arrays as received to l as a numpy array. It covers building the dense matrix
Siconos takes (for fc2d with each contact's normal and tangent rows side by side, Siconos'
layout), the problem and options objects (``setup_time_s``), the driver call
(``solve_time_s``) and reading l back in qpbench's order. Python's cyclic garbage collector
is paused inside, as qpbench's stopwatch pauses it. What Siconos prints on stdout is
discarded (the answers go to a private copy of stdout).
"""

from __future__ import annotations

import gc
import json
import os
import signal
import sys
import time
import traceback
from typing import Any, BinaryIO

import numpy as np


def die_with_parent() -> None:
    """Asks Linux to end this process when the process that started it ends (even by kill -9).

    So no server outlives its worker; a no-op elsewhere.
    """
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() == 1:
        os._exit(1)


def read_exactly(stream: BinaryIO, size: int) -> bytes:
    """``size`` bytes from ``stream``.

    Parameters
    ----------
    stream : BinaryIO
        The stream to read.
    size : int
        The number of bytes.

    Returns
    -------
    bytes
        Exactly ``size`` bytes.

    Raises
    ------
    EOFError
        When the stream ends first.
    """
    chunks = []
    left = size
    while left > 0:
        chunk = stream.read(left)
        if not chunk:
            raise EOFError("the stream ended inside a message")
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


def receive(stream: BinaryIO) -> tuple[dict[str, Any], dict[str, np.ndarray]] | None:
    """The next message (header, arrays), or None when the stream has ended.

    Parameters
    ----------
    stream : BinaryIO
        The stream to read, at the start of a message.

    Returns
    -------
    tuple[dict[str, Any], dict[str, np.ndarray]] or None
        The header without its ``arrays`` list, and the arrays by name (read-only views of
        the bytes read); None at the stream's end.

    Raises
    ------
    EOFError
        When the stream ends inside a message.
    """
    line = stream.readline()
    if not line:
        return None
    header = json.loads(line)
    arrays = {}
    for name, dtype, shape in header.pop("arrays", []):
        kind = np.dtype(dtype)
        count = int(np.prod(shape, dtype=np.int64))
        arrays[name] = np.frombuffer(read_exactly(stream, count * kind.itemsize),
                                     dtype=kind).reshape(shape)
    return header, arrays


def send(stream: BinaryIO, header: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
    """Writes one message and flushes it.

    Parameters
    ----------
    stream : BinaryIO
        The stream to write.
    header : dict[str, Any]
        The JSON header; the ``arrays`` list is added to a copy of it.
    arrays : dict[str, np.ndarray]
        The arrays by name, written in that order in C order.
    """
    contiguous = {name: np.ascontiguousarray(array) for name, array in arrays.items()}
    header = {**header, "arrays": [[name, array.dtype.str, list(array.shape)]
                                   for name, array in contiguous.items()]}
    stream.write(json.dumps(header).encode("utf-8") + b"\n")
    for array in contiguous.values():
        stream.write(array.tobytes())
    stream.flush()


def dense_from_csc(data: np.ndarray, indices: np.ndarray, indptr: np.ndarray,
                   size: int) -> np.ndarray:
    """The dense ``size x size`` matrix of CSC arrays (duplicates summed), Fortran order.

    Parameters
    ----------
    data, indices, indptr : np.ndarray
        The matrix in CSC form.
    size : int
        Its number of rows and columns.

    Returns
    -------
    np.ndarray
        The dense matrix, Fortran order.
    """
    matrix = np.zeros((size, size), order="F")
    columns = np.repeat(np.arange(size), np.diff(indptr))
    np.add.at(matrix, (indices, columns), data)
    return matrix


def solve(numerics: Any, header: dict[str, Any], arrays: dict[str, np.ndarray]
          ) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """One request's answer (see the module docstring).

    An exception of Siconos becomes the answer's ``error``, with ``info`` -1 and an empty l.

    Parameters
    ----------
    numerics : Any
        The ``siconos.numerics`` module.
    header : dict[str, Any]
        The request's header: ``problem`` (``lcp`` or ``fc2d``), ``solver``, ``iparam``,
        ``dparam``.
    arrays : dict[str, np.ndarray]
        The request's arrays: the CSC arrays of Q (or W), ``q`` and, for fc2d, ``mu``.

    Returns
    -------
    answer : dict[str, Any]
        The answer's header: ``info``, ``iterations``, ``residual``, the times and
        ``error``.
    arrays : dict[str, np.ndarray]
        ``l``, in qpbench's order, little-endian float64.
    """
    q = arrays["q"]
    size = int(q.shape[0])
    setup_time_s = solve_time_s = float("nan")
    collecting = gc.isenabled()
    gc.disable()
    start = time.perf_counter()
    try:
        matrix = dense_from_csc(arrays["data"], arrays["indices"], arrays["indptr"], size)
        if header["problem"] == "fc2d":
            contacts = size // 2
            # Siconos' layout: contact k's normal at 2k, its tangent at 2k + 1
            order = np.arange(size).reshape(2, contacts).T.ravel()
            matrix = np.asfortranarray(matrix[np.ix_(order, order)])
            q = q[order]
        else:
            q = np.array(q)
        setup_start = time.perf_counter()
        options = numerics.SolverOptions(getattr(numerics, header["solver"]))
        for index, value in header.get("iparam", {}).items():
            options.iparam[int(index)] = int(value)
        for index, value in header.get("dparam", {}).items():
            options.dparam[int(index)] = float(value)
        unknowns = np.zeros(size)
        velocities = np.zeros(size)
        if header["problem"] == "fc2d":
            problem = numerics.FrictionContactProblem(2, contacts, matrix, q,
                                                      np.array(arrays["mu"]))
            solve_start = time.perf_counter()
            info = numerics.fc2d_driver(problem, unknowns, velocities, options)
            solve_time_s = time.perf_counter() - solve_start
            impulses = np.concatenate([unknowns[0::2], unknowns[1::2]])
        else:
            problem = numerics.LCP(matrix, q)
            solve_start = time.perf_counter()
            info = numerics.linearComplementarity_driver(problem, unknowns, velocities, options)
            solve_time_s = time.perf_counter() - solve_start
            impulses = unknowns
        setup_time_s = solve_start - setup_start
        error = None
    except Exception as failure:  # a Siconos error is this solve's answer, not the server's end
        info, impulses, options, error = -1, np.zeros(0), None, f"{type(failure).__name__}: " \
            f"{' '.join(str(failure).split())}"
    elapsed = time.perf_counter() - start
    if collecting:
        gc.enable()
    answer = {
        "info": int(info),
        "iterations": None if options is None else
        int(options.iparam[numerics.SICONOS_IPARAM_ITER_DONE]),
        "residual": None if options is None else
        float(options.dparam[numerics.SICONOS_DPARAM_RESIDU]),
        "time_s": elapsed,
        "setup_time_s": setup_time_s,
        "solve_time_s": solve_time_s,
        "error": error,
    }
    return answer, {"l": np.asarray(impulses, dtype="<f8")}


def probe(solver_ids: list[str]) -> dict[str, Any]:
    """Siconos' version (the package's and Debian's) and which asked solvers it lacks.

    Parameters
    ----------
    solver_ids : list[str]
        Names of Siconos solver ids (``SICONOS_LCP_LEMKE``).

    Returns
    -------
    dict[str, Any]
        ``version``, ``debian``, ``numpy`` and ``missing``: each asked id that this build
        cannot run, with why.
    """
    import siconos
    import siconos.numerics as numerics

    missing = {}
    for solver_id in solver_ids:
        if not hasattr(numerics, solver_id):
            missing[solver_id] = "not in this Siconos build"
        elif solver_id == "SICONOS_LCP_NSQP" and not getattr(siconos, "WITH_QL0001", True):
            missing[solver_id] = "this Siconos build has no ql0001 (WITH_QL0001 off), which " \
                                 "NSQP needs"
    return {"version": str(getattr(siconos, "version", "unknown")), "debian": debian_version(),
            "numpy": np.__version__, "missing": missing}


def debian_version() -> str:
    """The version of Debian's python3-siconos from dpkg's status file.

    Returns
    -------
    str
        The version, '' when the file or the package is not found.
    """
    try:
        with open("/var/lib/dpkg/status", encoding="utf-8", errors="replace") as status:
            package = ""
            for line in status:
                if line.startswith("Package: "):
                    package = line[9:].strip()
                elif package == "python3-siconos" and line.startswith("Version: "):
                    return line[9:].strip()
    except OSError:
        pass
    return ""


def main() -> None:
    """Serve solve requests on stdin until it closes, or answer ``--probe`` and exit.

    Siconos' own printing is discarded; a failure of the server itself is printed on the
    worker's stderr and ends it with exit status 1.
    """
    if sys.argv[1:2] == ["--probe"]:
        print(json.dumps(probe(sys.argv[2:])))
        return
    die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the worker's to handle
    answers = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    errors = os.fdopen(os.dup(sys.stderr.fileno()), "w")
    quiet = os.open(os.devnull, os.O_WRONLY)
    # Siconos' own printing (warnings on stdout, LU failures on stderr) goes nowhere; the
    # answers carry its outcome
    os.dup2(quiet, sys.stdout.fileno())
    os.dup2(quiet, sys.stderr.fileno())
    try:
        import siconos.numerics as numerics

        requests = sys.stdin.buffer
        while (message := receive(requests)) is not None:
            header, arrays = message
            if header.get("problem") == "ping":
                send(answers, {"pong": True}, {})
                continue
            answer, answer_arrays = solve(numerics, header, arrays)
            send(answers, answer, answer_arrays)
    except BrokenPipeError:  # the worker has gone
        return
    except BaseException:  # the server's own failure: on the worker's stderr
        traceback.print_exc(file=errors)
        errors.flush()
        raise SystemExit(1) from None


if __name__ == "__main__":
    main()
