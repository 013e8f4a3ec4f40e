"""Siconos' LCP and 2D friction solvers, run by the system interpreter behind a pipe.

Siconos (Acary, Bremond, Huber; https://github.com/siconos/siconos) comes from Debian as
``python3-siconos``, built for /usr/bin/python3 and Debian's numpy, so it cannot be imported
here. Each process (a bench worker, a test session) starts one persistent server,
``siconos_server.py`` under /usr/bin/python3, in :func:`prepare` (outside any clock) and
sends it each posed problem as plain arrays: for ``lcp`` the CSC arrays of Q and b, for
``fc2d`` those of W (``r = (l_N, l_T)``), q and mu. The server measures its own time across
qpbench's one boundary (from the arrays it received to l as a numpy array: the dense matrix
Siconos takes, its problem and options, the solve, reading l back) and returns it with l,
Siconos' ``info``, its iteration count and residual; these pairs are registered with
``reports_own_time``, so that time becomes ``time_s`` and the pipe's round trip is kept
apart (docs/design.md section 7). Siconos' own split (its problem and options objects, the
driver call) is ``backend_setup_time_s`` / ``backend_solve_time_s``. Before each request the
server is moved to the CPU its client runs on (:meth:`SiconosServer.ask`), so that it finds
the caches as the client's other work left them, as a library called in-process would; on
another core it would find them as its own last solve left them, a cold start the other
solvers do not escape.

Pairs: ``lcp`` (impact problems) with Siconos' LCP solvers that apply to a symmetric
positive semi-definite Q; ``fc2d`` (frictional problems) with its 2D friction solvers, which
take a dense W. ``claimed_success`` is Siconos' ``info == 0``. Tolerance, iteration limit
and the size above which a dense or enumerative solver declines come from the accuracy
table. Every pair is unusable, with the reason, when /usr/bin/python3 cannot import
``siconos.numerics``; a solver this Siconos build lacks (NSQP without ql0001) is unusable
with its own reason.
"""

from __future__ import annotations

import atexit
import ctypes
import json
import os
import subprocess
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np
import scipy.sparse as sp

from qpbench.problem import metrics
from qpbench.problem.friction import FrictionalProblem
from qpbench.problem.impact import ImpactProblem
from qpbench.solvers import accuracy
from qpbench.solvers.base import OWN_TIME, SolverOutput, SolverSpec, reported_times
from qpbench.solvers.registry import register, register_unusable
from qpbench.solvers.siconos_server import receive, send

BACKEND = "siconos"
SYSTEM_PYTHON = "/usr/bin/python3"
SERVER = Path(__file__).with_name("siconos_server.py")
PROBE_TIMEOUT_S = 60.0
# Siconos' indices into its solver options (SolverOptions.h; LCP_Solvers.h, lcp_cst.h)
IPARAM_MAX_ITER = 0
DPARAM_TOL = 0


@dataclass(frozen=True)
class Pair:
    """One Siconos solver as a qpbench pair: its name, formulation, Siconos solver id and the
    accuracy-table key of the size above which it declines."""

    name: str
    formulation: str
    solver_id: str
    size_limit: str
    description: str


LCP_PAIRS = (
    Pair("siconos-lemke", "lcp", "SICONOS_LCP_LEMKE", "max_contacts",
         "Siconos' lexicographic Lemke (dense tableau)"),
    Pair("siconos-pivot", "lcp", "SICONOS_LCP_PIVOT", "max_contacts",
         "Siconos' pivoting method (Lemke's by default, dense)"),
    Pair("siconos-pivot-lumod", "lcp", "SICONOS_LCP_PIVOT_LUMOD", "max_contacts",
         "Siconos' Lemke with LU updates of the basis (LUMOD)"),
    Pair("siconos-murty", "lcp", "SICONOS_LCP_MURTY", "max_contacts",
         "Siconos' Murty least-index pivoting (dense)"),
    Pair("siconos-pgs", "lcp", "SICONOS_LCP_PGS", "max_contacts",
         "Siconos' projected Gauss-Seidel (dense)"),
    Pair("siconos-psor", "lcp", "SICONOS_LCP_PSOR", "max_contacts",
         "Siconos' projected SOR (dense)"),
    Pair("siconos-rpgs", "lcp", "SICONOS_LCP_RPGS", "max_contacts",
         "Siconos' regularized projected Gauss-Seidel (proximal point, for PSD Q)"),
    Pair("siconos-cpg", "lcp", "SICONOS_LCP_CPG", "max_contacts",
         "Siconos' conjugate projected gradient"),
    Pair("siconos-newton-min", "lcp", "SICONOS_LCP_NEWTONMIN", "max_contacts",
         "Siconos' semismooth Newton on the min function"),
    Pair("siconos-newton-fb", "lcp", "SICONOS_LCP_NEWTON_FB_FBLSA", "max_contacts",
         "Siconos' Newton on Fischer-Burmeister with line search"),
    Pair("siconos-newton-min-fb", "lcp", "SICONOS_LCP_NEWTON_MIN_FBLSA", "max_contacts",
         "Siconos' Newton on the min function with a Fischer-Burmeister line search"),
    Pair("siconos-nsqp", "lcp", "SICONOS_LCP_NSQP", "max_contacts",
         "Siconos' nonsymmetric QP solver (ql0001)"),
    Pair("siconos-enum", "lcp", "SICONOS_LCP_ENUM", "max_contacts",
         "Siconos' enumeration of complementary bases (2^n)"),
)
FRICTION_PAIRS = (
    Pair("siconos-nsgs", "fc2d", "SICONOS_FRICTION_2D_NSGS", "max_contacts",
         "Siconos' fc2d nonsmooth Gauss-Seidel (dense W)"),
    Pair("siconos-lemke", "fc2d", "SICONOS_FRICTION_2D_LEMKE", "max_frictional_contacts",
         "Siconos' fc2d Lemke on its LCP of the 2D law"),
    Pair("siconos-cpg", "fc2d", "SICONOS_FRICTION_2D_CPG", "max_frictional_contacts",
         "Siconos' fc2d conjugate projected gradient"),
    Pair("siconos-enum", "fc2d", "SICONOS_FRICTION_2D_ENUM", "max_frictional_contacts",
         "Siconos' fc2d enumeration on its LCP of the 2D law"),
)
PAIRS = LCP_PAIRS + FRICTION_PAIRS


def _cpu_reader() -> Callable[[], int] | None:
    """The C library's ``sched_getcpu`` (the CPU the calling thread runs on), or None where
    there is none (not Linux) or it fails."""
    try:
        current = ctypes.CDLL(None, use_errno=True).sched_getcpu
    except (OSError, AttributeError):
        return None
    current.restype, current.argtypes = ctypes.c_int, []
    return current if current() >= 0 else None


class SiconosServer:
    """The server process of this process (:func:`server`): one request at a time."""

    def __init__(self) -> None:
        self.owner = os.getpid()
        self.process = subprocess.Popen(
            [SYSTEM_PYTHON, "-I", str(SERVER)], stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, close_fds=True)
        self.read_cpu = _cpu_reader()
        self.server_cpu = -1  # the CPU the server was last moved to; -1: none yet
        self.ask({"problem": "ping"}, {})

    def _share_client_cpu(self) -> None:
        """Moves the server to the CPU this process runs on (while this process waits for
        the answer, the server runs there alone). A no-op where the CPU cannot be read or set,
        or when the server is there already."""
        if self.read_cpu is None:
            return
        cpu = self.read_cpu()
        if cpu < 0 or cpu == self.server_cpu:
            return
        try:
            os.sched_setaffinity(self.process.pid, {cpu})
        except (OSError, AttributeError):  # not allowed there, or not Linux
            self.read_cpu = None
            return
        self.server_cpu = cpu

    def alive(self) -> bool:
        """Whether the server runs and was started by this process (not one it forked from).

        Returns
        -------
        bool
            True when this process may still send it requests.
        """
        return self.owner == os.getpid() and self.process.poll() is None

    def ask(self, header: dict[str, Any], arrays: dict[str, np.ndarray]
            ) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """Sends one request, on the CPU this process runs on, and reads its answer.

        Parameters
        ----------
        header : dict[str, Any]
            The request's JSON header (``problem``, ``solver``, ``iparam``, ``dparam``; or
            ``{"problem": "ping"}``).
        arrays : dict[str, np.ndarray]
            The request's arrays by name (see ``siconos_server``).

        Returns
        -------
        header : dict[str, Any]
            The answer's header.
        arrays : dict[str, np.ndarray]
            The answer's arrays (``l`` for a solve).

        Raises
        ------
        RuntimeError
            When the server has ended (with the reason and its exit status).
        """
        stdin: IO[bytes] | None = self.process.stdin
        stdout: IO[bytes] | None = self.process.stdout
        assert stdin is not None and stdout is not None
        self._share_client_cpu()
        try:
            send(stdin, header, arrays)  # type: ignore[arg-type]
            answer = receive(stdout)  # type: ignore[arg-type]
        except (OSError, EOFError, ValueError) as error:
            answer = None
            reason = f"{type(error).__name__}: {error}"
        else:
            reason = "no answer"
        if answer is None:
            code = self.process.wait(timeout=5)
            raise RuntimeError(f"the Siconos server ended ({reason}; exit status {code})")
        return answer

    def close(self) -> None:
        """Ends the server (closing its stdin ends its loop)."""
        if self.owner != os.getpid():
            return
        for stream in (self.process.stdin, self.process.stdout):
            if stream is not None:
                stream.close()
        try:
            self.process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


_SERVER: SiconosServer | None = None


def server() -> SiconosServer:
    """This process's server, started if there is none.

    Also started anew when it ended, or when it belongs to the process this one was forked
    from.

    Returns
    -------
    SiconosServer
        The running server of this process.
    """
    global _SERVER
    if _SERVER is None or not _SERVER.alive():
        _SERVER = SiconosServer()
    return _SERVER


def prepare() -> None:
    """Starts this process's server (and imports Siconos there), outside any clock."""
    server()


@atexit.register
def _close_server() -> None:
    """Ends this process's server when the process ends normally."""
    if _SERVER is not None:
        _SERVER.close()


def probe() -> tuple[dict[str, Any] | None, str]:
    """Whether /usr/bin/python3 can import ``siconos.numerics``, and what it has.

    Runs the server script once with ``--probe`` and every pair's solver id.

    Returns
    -------
    found : dict[str, Any] or None
        Siconos' versions (``version``, ``debian``, ``numpy``) and ``missing``, the solver
        ids this build lacks with why; None when Siconos cannot be imported.
    reason : str
        Why not, in one line; empty when ``found`` is given.
    """
    if not os.access(SYSTEM_PYTHON, os.X_OK):
        return None, f"{SYSTEM_PYTHON} not found (Siconos runs in the system interpreter)"
    ids = [pair.solver_id for pair in PAIRS]
    try:
        done = subprocess.run([SYSTEM_PYTHON, "-I", str(SERVER), "--probe", *ids],
                              capture_output=True, text=True, timeout=PROBE_TIMEOUT_S)
    except (OSError, subprocess.TimeoutExpired) as error:
        return None, f"{SYSTEM_PYTHON} could not be run: {error}"
    if done.returncode != 0:
        lines = done.stderr.strip().splitlines()
        return None, f"{SYSTEM_PYTHON} cannot import siconos.numerics " \
                     f"({lines[-1] if lines else f'exit status {done.returncode}'}); " \
                     "install Debian's python3-siconos (make setup)"
    return json.loads(done.stdout), ""


def csc_arrays(matrix: sp.spmatrix) -> dict[str, np.ndarray]:
    """The CSC arrays of ``matrix`` as the server reads them.

    Parameters
    ----------
    matrix : sp.spmatrix
        A square sparse matrix (Q or W).

    Returns
    -------
    dict[str, np.ndarray]
        ``data`` (little-endian float64), ``indices`` and ``indptr`` (little-endian int64).
    """
    csc = sp.csc_matrix(matrix)
    return {"data": np.asarray(csc.data, dtype="<f8"),
            "indices": np.asarray(csc.indices, dtype="<i8"),
            "indptr": np.asarray(csc.indptr, dtype="<i8")}


def status_of(info: int, error: str | None) -> str:
    """Siconos' own outcome in words: its ``info`` (0: converged) or the error it raised.

    Parameters
    ----------
    info : int
        The driver's return value.
    error : str or None
        The text of the exception the solve raised in the server; None when none.

    Returns
    -------
    str
        ``error: ...``, or ``info N (converged)`` / ``info N (not converged)``.
    """
    if error is not None:
        return f"error: {error}"
    return f"info {info} ({'converged' if info == 0 else 'not converged'})"


def make_solve(pair: Pair) -> Callable[..., SolverOutput]:
    """The solve function of ``pair``.

    Parameters
    ----------
    pair : Pair
        The Siconos solver and its formulation (``lcp`` or ``fc2d``).

    Returns
    -------
    Callable[..., SolverOutput]
        ``solve(problem, eps, warm_start=None)`` (no warm start is used): sends Q and b (or
        W, q and mu) to the server with the pair's tolerance and iteration limit for
        ``eps``; declines above the pair's size limit; its claim is Siconos' ``info == 0``,
        ``info[OWN_TIME]`` the server's own time.
    """

    def solve(problem: ImpactProblem | FrictionalProblem, eps: float,
              warm_start: np.ndarray | None = None) -> SolverOutput:
        frictional = isinstance(problem, FrictionalProblem)
        options = accuracy.options_for(pair.name, eps, problem.scale if frictional
                                       else metrics.scale(problem))
        contacts = problem.n_contacts
        limit = int(options[pair.size_limit])
        if contacts > limit:
            return SolverOutput(impulses=None, claimed_success=False,
                                status=f"declined: {contacts} contacts > {pair.size_limit} "
                                       f"{limit}")
        if contacts == 0:
            return SolverOutput(impulses=np.zeros(0), status="no contacts",
                                claimed_success=True, iterations=0)
        if frictional:
            arrays = {**csc_arrays(problem.W), "q": np.asarray(problem.q, dtype="<f8"),
                      "mu": np.asarray(problem.mu, dtype="<f8")}
        else:
            arrays = {**csc_arrays(problem.Q), "q": np.asarray(problem.b, dtype="<f8")}
        header = {"problem": pair.formulation, "solver": pair.solver_id,
                  "iparam": {str(IPARAM_MAX_ITER): int(options["max_iter"])},
                  "dparam": {str(DPARAM_TOL): float(options["tol"])}}
        answer, answer_arrays = server().ask(header, arrays)
        impulses = answer_arrays.get("l")
        error = answer.get("error")
        return SolverOutput(
            impulses=None if error is not None or impulses is None else np.array(impulses),
            status=status_of(int(answer["info"]), error),
            claimed_success=error is None and int(answer["info"]) == 0,
            iterations=answer.get("iterations"),
            backend_times=reported_times(backend_setup_time_s=answer.get("setup_time_s"),
                                         backend_solve_time_s=answer.get("solve_time_s")),
            info={OWN_TIME: float(answer["time_s"]), "siconos_info": int(answer["info"]),
                  "siconos_residual": answer.get("residual")})

    return solve


def _register_all() -> None:
    found, reason = probe()
    if found is None:
        for pair in PAIRS:
            register_unusable(pair.name, (pair.formulation,), BACKEND, reason)
        return
    version = (f"{found['debian']} (Debian python3-siconos; siconos.version "
               f"{found['version']})" if found.get("debian") else found["version"])
    for pair in PAIRS:
        kinds = ("frictional",) if pair.formulation == "fc2d" else ("impact",)
        missing = found["missing"].get(pair.solver_id, "")
        register(SolverSpec(name=pair.name, formulation=pair.formulation, backend=BACKEND,
                            solve=None if missing else make_solve(pair), version=version,
                            warm_start=False, description=pair.description, reason=missing,
                            prepare=prepare, reports_own_time=True, kinds=kinds))


_register_all()
