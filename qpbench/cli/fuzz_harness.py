"""``qpbench fuzz``: mutated scenes and problem files through the real command line.

Each case (:mod:`qpbench.bench.fuzz_inputs` makes its input from the run's seed and the
case's number) is written to a file and run through :func:`qpbench.cli.main`, in-process in a
child process forked from this one: a scene by ``qpbench simulate SCENE --steps K --accuracy
1e-4 --capture DIR --json`` (parse, K steps, every impact written as a problem file), a problem
file by ``qpbench solve FILE --solver NAME --accuracy 1e-4 --json`` with a cheap solver
(``pi-robust`` and ``pgs`` in turn). The accuracy is looser than the default 1e-8 because
the cases test reading and checking, not the solvers: a frictional pile asked for 1e-8 can
spend minutes of Gauss-Seidel sweeps on one step. Children run batches of :data:`BATCH`
cases under an address-space cap (the child's size when forked plus ``memory_limit_mb``,
through ``RLIMIT_AS``); a case that runs past ``time_limit_s`` is killed with its child, and
the next child goes on with the rest.

:func:`judge` gives every case one outcome. Passing: ``ok`` (exit 0, stderr holds only
``qpbench COMMAND: warning:``/``note:`` lines), ``solve-failed`` (exit 1) and ``input-error``
(exit 2), each with exactly one other stderr line, which starts ``qpbench `` and is at most
:data:`MAX_LINE` characters long. Failing: ``internal-error`` (exit 3), ``out-of-memory``,
``traceback``, ``stray-stderr`` (a line not from qpbench, such as a Python warning),
``several-lines``, ``no-message``, ``overlong-line``, ``other-exit``, ``entity-accepted`` (a
scene declaring an entity read without refusal), ``timeout`` and ``crashed`` (the child died).
A failing case's input is saved in a folder beside the report, with the command that
reproduces it.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import multiprocessing
import os
import resource
import shutil
import signal
import tempfile
import time
import traceback
import warnings
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import defusedxml.ElementTree as SafeET

from qpbench.cli import build_parser, main
from qpbench.cli.fuzz_inputs import Mutated, case_rng, mutate_problem, mutate_scene
from qpbench.errors import InputError, QpbenchError
from qpbench.memory import virtual_memory_mb
from qpbench.scenes.parser import KNOWN_ATTRIBUTES, NESTED_ATTRIBUTES

REPOSITORY = Path(__file__).resolve().parents[2]
# where the scenes to mutate come from, when no corpus is named: the repository's copies and
# the shared SCISim scenes beside the repository, where they are
DEFAULT_SCENE_FOLDERS = (REPOSITORY / "problems" / "scenes",
                         REPOSITORY.parent / "shared" / "scisim",
                         REPOSITORY.parent / "shared" / "scenes")
MAX_CORPUS_SCENE_BYTES = 64_000
MAX_SCENES_PER_FOLDER = 12  # the fork's folders of 50 grid scenes do not crowd out the rest
SOLVERS = ("pi-robust", "pgs")
ACCURACY = "1e-4"
# the commands the cases run (their modules are imported before the children fork)
FUZZED_COMMANDS = ("simulate", "solve", "generate")
BATCH = 200
MAX_LINE = 1000
KINDS = ("scene", "problem")
PASSING = ("ok", "solve-failed", "input-error")
STDERR_KEPT = 2000
# the problem files mutated: generated families, frictional ones included, and scene captures
GENERATED = (("k3",), ("cradle",), ("grid", "--size", "3"), ("near-duplicate",),
             ("mass-ratio",), ("incline", "--size", "3"), ("rough-box", "--size", "4"),
             ("k4", "--no-reference"))
CAPTURED = ("ura/K4.xml", "ura/grid3_itr_0.xml", "piles/circle_pile_30.xml")


@dataclass(frozen=True)
class Settings:
    """What a fuzz run does: cases per kind, the seed, simulated steps per scene, and the
    limits of every case."""

    scenes: int
    problems: int
    seed: int = 0
    steps: int = 3
    time_limit_s: float = 30.0
    memory_limit_mb: int = 1024


@dataclass
class Corpus:
    """The inputs mutated: (name, bytes) of scenes and of problem files."""

    scenes: list[tuple[str, bytes]]
    problems: list[tuple[str, bytes]]

    def digest(self) -> str:
        """SHA-256 over every name and content of the corpus.

        A case is reproducible from the seed and its number with a corpus of the same digest.

        Returns
        -------
        str
            The digest in hexadecimal.
        """
        hasher = hashlib.sha256()
        for name, data in [*self.scenes, *self.problems]:
            hasher.update(name.encode() + b"\0" + hashlib.sha256(data).digest())
        return hasher.hexdigest()


# --- the corpus ----------------------------------------------------------------------------
def scene_corpus(folders: list[Path]) -> list[tuple[str, bytes]]:
    """The scene files under ``folders`` whose XML reads with a SCISim 2D root.

    At most MAX_SCENES_PER_FOLDER per folder, each at most MAX_CORPUS_SCENE_BYTES, identical
    contents once.

    Parameters
    ----------
    folders : list of Path
        The folders searched, recursively, for ``*.xml``.

    Returns
    -------
    list of (str, bytes)
        Each scene's name (relative to the repository's parent folder where it lies inside it)
        and its bytes.

    Raises
    ------
    InputError
        When a folder does not exist, or no scene qualifies.
    """
    found: list[tuple[str, bytes]] = []
    seen: set[bytes] = set()
    for folder in folders:
        if not folder.is_dir():
            raise InputError(str(folder), "no such corpus folder")
        per_folder: Counter[Path] = Counter()
        for path in sorted(folder.rglob("*.xml")):
            if path.stat().st_size > MAX_CORPUS_SCENE_BYTES:
                continue
            if per_folder[path.parent] >= MAX_SCENES_PER_FOLDER:
                continue
            data = path.read_bytes()
            digest = hashlib.sha256(data).digest()
            if digest in seen:
                continue
            try:
                root = SafeET.fromstring(data)
            except Exception:  # a corpus file that does not read is left out (any XML fault)
                continue
            if root.tag not in ("ball2d_scene", "rigidbody2d_scene"):
                continue
            seen.add(digest)
            per_folder[path.parent] += 1
            found.append((_display(path), data))
    if not found:
        raise InputError(", ".join(str(folder) for folder in folders),
                         "no SCISim 2D scene to mutate in these folders")
    return found


def _display(path: Path) -> str:
    """``path`` relative to the repository's parent folder where it lies inside it (as named,
    links not followed: ../shared may be a link to the shared folder)."""
    try:
        return str(path.absolute().relative_to(REPOSITORY.parent))
    except ValueError:
        return str(path)


def problem_corpus(work: Path) -> list[tuple[str, bytes]]:
    """The problem files to mutate, written through the command line.

    Problem files written by ``qpbench generate`` (the GENERATED families) and by ``qpbench
    simulate --capture`` (the CAPTURED scenes, and a pile that carries a warm start), run here
    through the command line.

    Parameters
    ----------
    work : Path
        The run's temporary folder; the files go to its ``corpus`` folder.

    Returns
    -------
    list of (str, bytes)
        Each file's name and its bytes.

    Raises
    ------
    QpbenchError
        When no problem file could be written.
    """
    folder = work / "corpus"
    for arguments in GENERATED:
        _quiet_main(["generate", *arguments, "-o", str(folder)])
    scenes = REPOSITORY / "problems" / "scenes"
    for name in CAPTURED:
        if (scenes / name).exists():
            _quiet_main(["simulate", str(scenes / name), "--steps", "3", "--capture",
                         str(folder)])
    pile = scenes / "piles" / "circle_pile_30.xml"
    if pile.exists():
        cached = work / "cached_pile.xml"
        cached.write_bytes(pile.read_bytes().replace(b'cache_impulses="0"',
                                                     b'cache_impulses="1"'))
        _quiet_main(["simulate", str(cached), "--steps", "3", "--capture", str(folder)])
    found = [(path.name, path.read_bytes()) for path in sorted(folder.glob("*.npz"))]
    if not found:
        raise QpbenchError("fuzz: could not write the problem files to mutate")
    return found


def _quiet_main(argv: list[str]) -> None:
    """Runs one qpbench command with its output dropped."""
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        main(argv)


# --- one case ------------------------------------------------------------------------------
def make_case(kind: str, case: int, settings: Settings, corpus: Corpus) -> Mutated:
    """The input of case ``case`` of ``kind`` (the same bytes for the same seed and corpus).

    Parameters
    ----------
    kind : str
        ``scene`` or ``problem``.
    case : int
        The case's number within its kind.
    settings : Settings
        The run's settings (its seed, and the memory cap for problem cases).
    corpus : Corpus
        The inputs mutated.

    Returns
    -------
    Mutated
        The mutated input.
    """
    rng = case_rng(kind, settings.seed, case)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # zipfile's duplicate-name warning and the like
        if kind == "scene":
            return mutate_scene(corpus.scenes, rng)
        return mutate_problem(corpus.problems, rng, settings.memory_limit_mb)


def case_file(kind: str, case: int) -> str:
    """The file name of a case's input: ``KIND-NNNNNN.xml`` or ``.npz``.

    Parameters
    ----------
    kind : str
        ``scene`` or ``problem``.
    case : int
        The case's number within its kind.

    Returns
    -------
    str
        The name, with ``.xml`` for a scene and ``.npz`` for a problem.
    """
    return f"{kind}-{case:06d}" + (".xml" if kind == "scene" else ".npz")


def command_for(kind: str, case: int, path: str, capture: str, settings: Settings) -> list[str]:
    """The qpbench arguments that run case ``case`` on ``path``.

    A scene is simulated (``simulate PATH --steps K --accuracy ACCURACY --capture DIR
    --json``), a problem solved by SOLVERS in turn (``solve PATH --solver NAME --accuracy
    ACCURACY --json``).

    Parameters
    ----------
    kind : str
        ``scene`` or ``problem``.
    case : int
        The case's number within its kind; it picks a problem case's solver.
    path : str
        The case's input file.
    capture : str
        The folder a scene case's impacts are captured to.
    settings : Settings
        The run's settings (the steps of a scene case).

    Returns
    -------
    list of str
        The arguments after ``qpbench``.
    """
    if kind == "scene":
        return ["simulate", path, "--steps", str(settings.steps), "--accuracy", ACCURACY,
                "--capture", capture, "--json"]
    return ["solve", path, "--solver", SOLVERS[case % len(SOLVERS)], "--accuracy", ACCURACY,
            "--json"]


def run_command(argv: list[str]) -> tuple[int, str]:
    """Run ``qpbench ARGV`` in this process and collect its exit status and stderr.

    Python warnings raised meanwhile are stderr lines as Python would print them; an exception
    that escapes is a traceback on stderr and exit 3.

    Parameters
    ----------
    argv : list of str
        The arguments after ``qpbench``.

    Returns
    -------
    tuple of (int, str)
        The exit status and everything written to stderr.
    """
    stderr = io.StringIO()
    with warnings.catch_warnings(record=True) as caught, \
            contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(stderr):
        warnings.simplefilter("always")
        try:
            status = main(argv)
        except SystemExit as exit_:  # argparse
            status = exit_.code if isinstance(exit_.code, int) else 2
        except BaseException:  # main lets nothing but KeyboardInterrupt and SystemExit out
            stderr.write(traceback.format_exc())
            status = 3
    text = stderr.getvalue()
    for warning in caught:
        text += warnings.formatwarning(warning.message, warning.category, warning.filename,
                                       warning.lineno, "").strip() + "\n"
    return int(status), text


def judge(exit_code: int, stderr: str, must_refuse: bool = False) -> str:
    """The outcome of a case (module docstring): one of PASSING, or a failure.

    Parameters
    ----------
    exit_code : int
        The command's exit status.
    stderr : str
        What it wrote on stderr.
    must_refuse : bool, optional
        Whether the input must be refused (a scene declaring an entity); False by default.

    Returns
    -------
    str
        The outcome's name: ``ok``, ``solve-failed``, ``input-error`` or a failure such as
        ``traceback`` or ``several-lines``.
    """
    lines = [line for line in stderr.splitlines() if line.strip()]
    if "Traceback (most recent call last)" in stderr:
        return "traceback"
    if exit_code == 3 or any("internal error" in line for line in lines):
        return "out-of-memory" if "MemoryError" in stderr else "internal-error"
    if any(not line.startswith("qpbench ") for line in lines):
        return "stray-stderr"
    if any(len(line) > MAX_LINE for line in lines):
        return "overlong-line"
    messages = [line for line in lines if not _is_commentary(line)]
    if exit_code == 0:
        if must_refuse:
            return "entity-accepted"
        return "ok" if not messages else "several-lines"
    if exit_code not in (1, 2):
        return "other-exit"
    if not messages:
        return "no-message"
    if len(messages) > 1:
        return "several-lines"
    return "solve-failed" if exit_code == 1 else "input-error"


def _is_commentary(line: str) -> bool:
    """``qpbench COMMAND: warning: ...`` or ``qpbench COMMAND: note: ...``."""
    _, _, rest = line.partition(": ")
    return rest.startswith(("warning: ", "note: "))


def _run_case(kind: str, case: int, settings: Settings, corpus: Corpus,
              work: Path) -> dict[str, Any]:
    """Makes, writes, runs and judges one case in this process."""
    started = time.perf_counter()
    mutated = make_case(kind, case, settings, corpus)
    path = work / case_file(kind, case)
    capture = work / "capture"
    path.write_bytes(mutated.data)
    try:
        exit_code, stderr = run_command(command_for(kind, case, str(path), str(capture),
                                                    settings))
    finally:
        path.unlink(missing_ok=True)
        shutil.rmtree(capture, ignore_errors=True)
    return {"kind": kind, "case": case, "exit_code": exit_code,
            "outcome": judge(exit_code, stderr, mutated.must_refuse),
            "stderr": stderr[:STDERR_KEPT], "seconds": time.perf_counter() - started,
            "operations": mutated.operations, "touched": mutated.touched,
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}


# --- children ------------------------------------------------------------------------------
def _child(connection: Any, cases: list[tuple[str, int]], settings: Settings, corpus: Corpus,
           work: Path) -> None:
    """A child's life: cap the address space, silence the inherited stdout and stderr (C
    libraries write there), run ``cases`` in order and send each result."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent stops the run
    cap = int((virtual_memory_mb() + settings.memory_limit_mb) * 1024 * 1024)
    _, hard = resource.getrlimit(resource.RLIMIT_AS)
    resource.setrlimit(resource.RLIMIT_AS, (cap if hard == resource.RLIM_INFINITY
                                            else min(cap, hard), hard))
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    child_work = work / f"child-{os.getpid()}"
    child_work.mkdir(exist_ok=True)
    for kind, case in cases:
        connection.send(_run_case(kind, case, settings, corpus, child_work))
    connection.close()


def _harness_result(kind: str, case: int, outcome: str, message: str) -> dict[str, Any]:
    return {"kind": kind, "case": case, "exit_code": None, "outcome": outcome,
            "stderr": message, "seconds": None, "operations": [], "touched": []}


def _run_batch(cases: list[tuple[str, int]], settings: Settings, corpus: Corpus,
               work: Path) -> list[dict[str, Any]]:
    """Runs ``cases`` in forked children: one child for the batch, a new one after a case
    that timed out or killed its child."""
    context = multiprocessing.get_context("fork")
    results: list[dict[str, Any]] = []
    pending = list(cases)
    while pending:
        receiver, sender = context.Pipe(duplex=False)
        child = context.Process(target=_child, args=(sender, pending, settings, corpus, work),
                                daemon=True)
        child.start()
        sender.close()
        try:
            while pending:
                kind, case = pending[0]
                if not receiver.poll(settings.time_limit_s):
                    results.append(_harness_result(kind, case, "timeout", "no answer within "
                                                   f"{settings.time_limit_s:g} s: killed"))
                    pending.pop(0)
                    break
                try:
                    results.append(receiver.recv())
                except (EOFError, OSError):
                    child.join(5)
                    results.append(_harness_result(kind, case, "crashed", "the child ended "
                                                   f"with exit status {child.exitcode}"))
                    pending.pop(0)
                    break
                pending.pop(0)
        finally:
            if child.is_alive():
                child.kill()
            child.join()
            receiver.close()
    return results


# --- the run -------------------------------------------------------------------------------
def fuzz(settings: Settings, scene_folders: list[Path] | None = None,
         cases_folder: Path | None = None) -> dict[str, Any]:
    """Run the scene and problem cases and report them.

    Runs ``settings.scenes`` scene cases and ``settings.problems`` problem cases in forked
    children, in batches of BATCH, after a warm-up here. The inputs of failing cases are written
    to ``cases_folder`` when given.

    Parameters
    ----------
    settings : Settings
        Cases per kind, the seed, steps and the limits of every case.
    scene_folders : list of Path or None, optional
        The folders of scenes to mutate; None (default) uses those of DEFAULT_SCENE_FOLDERS that
        exist.
    cases_folder : Path or None, optional
        The folder for the failing cases' inputs; None (default) writes none.

    Returns
    -------
    dict
        The report of :func:`summarize` (counts per outcome and mutation, attribute coverage,
        the failures), with ``wall_s``, the run's wall-clock seconds.

    Raises
    ------
    QpbenchError
        When the corpus cannot be gathered.
    """
    started = time.perf_counter()
    folders = scene_folders or [folder for folder in DEFAULT_SCENE_FOLDERS if folder.is_dir()]
    for command in FUZZED_COMMANDS:  # imported once, before the children fork
        build_parser(only=command)
    work = Path(tempfile.mkdtemp(prefix="qpbench-fuzz-"))
    try:
        corpus = Corpus(scenes=scene_corpus(folders),
                        problems=problem_corpus(work) if settings.problems else [])
        _warm_up(settings, corpus, work)
        cases = ([("scene", case) for case in range(settings.scenes)]
                 + [("problem", case) for case in range(settings.problems)])
        results: list[dict[str, Any]] = []
        for start in range(0, len(cases), BATCH):
            results.extend(_run_batch(cases[start:start + BATCH], settings, corpus, work))
    finally:
        shutil.rmtree(work, ignore_errors=True)
    report = summarize(results, settings, corpus, folders)
    if cases_folder is not None and report["failures"]:
        _save_failures(report["failures"], settings, corpus, cases_folder)
    report["wall_s"] = round(time.perf_counter() - started, 1)
    return report


def _warm_up(settings: Settings, corpus: Corpus, work: Path) -> None:
    """Runs an unmutated scene and every solver once here, so the children inherit loaded
    backends and compiled kernels instead of each paying for them."""
    warm = work / "warm-up"
    warm.mkdir()
    scene = warm / "scene.xml"
    scene.write_bytes(corpus.scenes[0][1])
    run_command(command_for("scene", 0, str(scene), str(warm / "capture"), settings))
    for index, (_, data) in enumerate(corpus.problems[:len(SOLVERS)]):
        problem = warm / "problem.npz"
        problem.write_bytes(data)
        run_command(command_for("problem", index, str(problem), "", settings))


def summarize(results: list[dict[str, Any]], settings: Settings, corpus: Corpus,
              folders: list[Path]) -> dict[str, Any]:
    """The report of a run from its case results.

    Parameters
    ----------
    results : list of dict
        One record per case (kind, case, exit status, outcome, stderr, seconds, operations,
        attributes touched, peak RSS).
    settings : Settings
        The run's settings.
    corpus : Corpus
        The inputs mutated.
    folders : list of Path
        The scene folders of the corpus.

    Returns
    -------
    dict
        The settings, whether every case passed, counts per kind (outcomes, operations, the
        slowest case, the peak RSS in MiB), the attribute coverage, the corpus with its digest,
        and the failing cases.
    """
    kinds: dict[str, Any] = {}
    for kind in KINDS:
        mine = [result for result in results if result["kind"] == kind]
        outcomes = Counter(result["outcome"] for result in mine)
        operations = Counter(operation.split(" ")[0] for result in mine
                             for operation in result["operations"])
        timed = [result for result in mine if result["seconds"] is not None]
        slowest = max(timed, key=lambda result: result["seconds"], default=None)
        kinds[kind] = {
            "cases": len(mine),
            "failed": sum(count for outcome, count in outcomes.items()
                          if outcome not in PASSING),
            "outcomes": dict(sorted(outcomes.items())),
            "operations": dict(sorted(operations.items())),
            "slowest_s": round(slowest["seconds"], 3) if slowest else None,
            "slowest_case": slowest["case"] if slowest else None,
            "peak_rss_mb": round(max((result.get("peak_rss_mb", 0.0) for result in mine),
                                     default=0.0), 1),
        }
    failures = [{key: result[key] for key in ("kind", "case", "outcome", "exit_code", "stderr",
                                              "operations")}
                for result in results if result["outcome"] not in PASSING]
    return {
        "seed": settings.seed, "steps": settings.steps, "time_limit_s": settings.time_limit_s,
        "memory_limit_mb": settings.memory_limit_mb, "solvers": list(SOLVERS),
        "accuracy": float(ACCURACY),
        "passed": not failures,
        "cases": len(results),
        "failed": len(failures),
        "kinds": kinds,
        "coverage": coverage(results),
        "corpus": {"folders": [_display(folder) for folder in folders],
                   "scenes": [name for name, _ in corpus.scenes],
                   "problems": [name for name, _ in corpus.problems],
                   "sha256": corpus.digest()},
        "failures": failures,
    }


def coverage(results: list[dict[str, Any]]) -> dict[str, Any]:
    """Per dialect, the attributes qpbench reads that some case touched, and those none did.

    An attribute is touched when some case set it to a bad value or deleted it.

    Parameters
    ----------
    results : list of dict
        The case records, each with ``touched``: (dialect, element, attribute) triples.

    Returns
    -------
    dict
        Per dialect: ``touched`` and ``known`` counts, and the ``untouched`` attributes as
        ``<element> 'attribute'``.
    """
    touched: dict[str, set[tuple[str, str]]] = {dialect: set() for dialect in KNOWN_ATTRIBUTES}
    for result in results:
        for dialect, element, attribute in result["touched"]:
            touched.setdefault(dialect, set()).add((element, attribute))
    report: dict[str, Any] = {}
    for dialect, elements in KNOWN_ATTRIBUTES.items():
        known = {(element, attribute) for element, names in {**elements,
                                                             **NESTED_ATTRIBUTES}.items()
                 for attribute in (names or ())}
        report[dialect] = {
            "touched": len(known & touched[dialect]), "known": len(known),
            "untouched": sorted(f"<{element}> '{attribute}'"
                                for element, attribute in known - touched[dialect]),
        }
    return report


def _save_failures(failures: list[dict[str, Any]], settings: Settings, corpus: Corpus,
                   folder: Path) -> None:
    """Writes each failing case's input to ``folder`` and names it, with the command that
    reproduces it, in its failure record; a case whose input cannot be made (a fault of the
    mutations, which its own run met first) says so in its record instead, and the report is
    still written."""
    folder.mkdir(parents=True, exist_ok=True)
    for failure in failures:
        kind, case = failure["kind"], failure["case"]
        try:
            mutated = make_case(kind, case, settings, corpus)
        except Exception as error:  # noqa: BLE001 (the harness's own fault, kept in the report)
            failure["input"] = f"not made: {type(error).__name__}: {error}"[:STDERR_KEPT]
            continue
        path = folder / case_file(kind, case)
        path.write_bytes(mutated.data)
        failure["base"] = mutated.base
        failure["operations"] = mutated.operations
        failure["input"] = str(path)
        failure["command"] = ["qpbench", *command_for(kind, case, str(path),
                                                      str(folder / "capture"), settings)]
