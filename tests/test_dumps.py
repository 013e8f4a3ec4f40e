"""SCISim LCP dumps import as problems, keep their dumped vectors, and refuse bad shapes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from qpbench.errors import InputError
from qpbench.problem import metrics
from qpbench.problem.dumps import import_dump

DUMPS = Path(__file__).resolve().parents[1] / "problems" / "dumps"
# named, not globbed: a dump missing from the repository fails its test instead of vanishing
DUMP_NAMES = ("2_balls.json", "grid5_itr_0.out", "grid5_itr_1.out", "ok_itr_0.out")
ALL_DUMPS = [DUMPS / name for name in DUMP_NAMES]


def test_the_repository_holds_exactly_these_dumps() -> None:
    assert sorted(path.name for path in DUMPS.iterdir()) == sorted(DUMP_NAMES)


@pytest.mark.parametrize("path", ALL_DUMPS, ids=lambda p: p.name)
def test_every_shared_dump_imports(path: Path) -> None:
    problem = import_dump(path)
    assert problem.family == "dump"
    assert problem.n_contacts > 0
    assert problem.restitution == pytest.approx(1.0)
    assert "ipopt_sol" in problem.data and "policy_sol" in problem.data
    if "Q" in problem.data:  # the dumped Q is N^T Minv N up to the printed digits
        assert problem.data["Q"] == pytest.approx(problem.Q.toarray(), abs=1e-5)


def test_json_dump_keeps_flags_times_and_b() -> None:
    problem = import_dump(DUMPS / "2_balls.json")
    assert problem.metadata["ipopt_converges"] is True
    assert problem.metadata["policy_v2_converges"] is False
    assert problem.metadata["ipopt_time"] == 21
    assert problem.data["b"] == pytest.approx(problem.b)
    assert problem.dofs_per_body == 3


def test_text_dump_derives_b_with_cor_one() -> None:
    problem = import_dump(DUMPS / "ok_itr_0.out")
    assert problem.metadata["layout"] == "text"
    assert problem.b == pytest.approx(2.0 * (problem.G.T @ problem.v_minus))
    assert problem.metadata["ipopt_converges"] == 0


def test_the_dumped_pi_answer_on_grid5_is_judged_not_trusted() -> None:
    problem = import_dump(DUMPS / "grid5_itr_0.out")
    # the fork's policy iteration claimed nothing here; qpbench measures it as far off
    assert metrics.residual(problem, problem.data["policy_sol"]) > 1e-3


def _write(tmp_path: Path, entries: dict) -> Path:
    path = tmp_path / "dump.json"
    path.write_text(json.dumps(entries) + "\n")
    return path


_TEXT_DUMP = ("N:\nsize: 4 1\n(0,0,-1) (2,0,1)\nMinv:\nsize: 4 4\n(0,0,1) (1,1,1) (2,2,1) (3,3,1)\n"
              "v0:\nsize: 4 1\n(0,0,1) (2,0,-1)\n")


def _pair() -> dict:
    return {
        "N": {"shape": [4, 1], "data": [[0, 0, -1.0], [2, 0, 1.0]]},
        "Minv": {"shape": [4, 4], "data": [[i, i, 1.0] for i in range(4)]},
        "v0": {"shape": [4, 1], "data": [[0, 0, 1.0], [2, 0, -1.0]]},
    }


def test_a_minimal_dump_is_a_problem(tmp_path: Path) -> None:
    problem = import_dump(_write(tmp_path, _pair()))
    assert problem.b == pytest.approx([-4.0])


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: d["v0"].update(shape=[3, 1]), r"<v0> attribute 'shape'"),
        (lambda d: d["Minv"].update(shape=[5, 5]), r"<Minv> attribute 'shape'"),
        (lambda d: d["N"].update(data=[[9, 0, 1.0]]), r"<N> attribute 'data'.*outside"),
        (lambda d: d["N"].pop("shape"), r"<N> attribute 'shape'"),
        (lambda d: d.pop("v0"), r"<v0>: missing"),
        (lambda d: d["Minv"]["data"].append([0, 1, 0.5]), r"<Minv>.*diagonal"),
        (lambda d: d.update(b={"shape": [1, 1], "data": [[0, 0, 7.0]]}), r"<b>.*CoR"),
        (lambda d: d["N"].update(shape=[4.5, 1]), r"<N> attribute 'shape': shape must be "
                                                  r"two integers, got \[4.5, 1\]"),
        (lambda d: d["N"].update(shape=[4, 1, 1]), r"<N> attribute 'shape'"),
        (lambda d: d["v0"].update(shape=[4, 10**12]), r"<v0> attribute 'shape'.*beyond"),
        (lambda d: d.update(Q={"shape": [2, 2], "data": []}), r"<Q> attribute 'shape'"),
        (lambda d: d.update(policy_sol={"shape": [1, 3], "data": []}),
         r"<policy_sol> attribute 'shape'"),
        # summed, a repeated entry would double N and pass as CoR 1/3
        (lambda d: d["N"]["data"].append([0, 0, -1.0]),
         r"<N> attribute 'data': entry \(0, 0\) appears more than once"),
    ],
)
def test_bad_dumps_name_the_entry_and_field(tmp_path: Path, change, message: str) -> None:
    entries = _pair()
    change(entries)
    with pytest.raises(InputError, match=message):
        import_dump(_write(tmp_path, entries))


def test_nan_in_a_dump_is_refused(tmp_path: Path) -> None:
    entries = _pair()
    entries["v0"]["data"][0][2] = float("nan")
    path = _write(tmp_path, entries)
    with pytest.raises(InputError, match="NaN"):
        import_dump(path)


def test_an_entry_given_twice_is_refused(tmp_path: Path) -> None:
    """json.loads and a plain dict would keep the second N silently."""
    text = json.dumps(_pair())
    twice = text.replace('"N":', '"N": {"shape": [4, 1], "data": [[1, 0, 1.0]]}, "N":', 1)
    path = tmp_path / "twice.out"
    path.write_text(twice)
    with pytest.raises(InputError, match=r"twice.out: <N>: appears more than once"):
        import_dump(path)


def test_a_key_given_twice_inside_an_entry_names_the_entry(tmp_path: Path) -> None:
    text = json.dumps(_pair()).replace('"shape":', '"shape": [9, 9], "shape":', 1)
    path = tmp_path / "inner.out"
    path.write_text(text)
    with pytest.raises(InputError, match=r"inner.out: <N> attribute 'shape': appears more "):
        import_dump(path)


def test_a_key_given_twice_deeper_down_is_refused_too(tmp_path: Path) -> None:
    entries = {**_pair(), "notes": [{"solver": "ipopt"}]}
    path = tmp_path / "deep.out"
    path.write_text(json.dumps(entries).replace('"solver": "ipopt"', '"solver": "ipopt", '
                                                '"solver": "pi"', 1))
    with pytest.raises(InputError, match=r"deep.out: <notes> attribute 'solver': appears "):
        import_dump(path)


def test_arrays_nested_beyond_reason_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "deep.out"
    path.write_text('{"N": ' + "[" * 100_000 + "]" * 100_000 + "}")
    with pytest.raises(InputError, match=r"deep.out: malformed dump: .* nested too deeply"):
        import_dump(path)


def test_a_text_entry_given_twice_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "twice.txt"
    path.write_text(_TEXT_DUMP + "N:\nsize: 4 1\n(0,0,-1) (2,0,1)\n")
    with pytest.raises(InputError, match=r"twice.txt: <N>: appears more than once"):
        import_dump(path)


def test_the_text_sample_is_a_problem(tmp_path: Path) -> None:
    path = tmp_path / "pair.txt"
    path.write_text(_TEXT_DUMP)
    assert import_dump(path).b == pytest.approx([-4.0])


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("(0,0,-1)", "(0,0,x)", r"<N> attribute 'data': a triplet part is not a number"),
        ("(0,0,1) (2", "(0,0,1) junk (2", r"<v0> attribute 'data': not an \(i,j,value\) "
                                           r"triplet: 'junk'"),
        ("v0:", "stray\nv0:", r"malformed dump: line 7 \('stray'\)"),
    ],
)
def test_text_dump_lines_are_read_whole(tmp_path: Path, old: str, new: str, message: str
                                        ) -> None:
    """Nothing in a text dump is skipped: a stray line or a word among the triplets is one
    line naming it, not a dump read with an entry left out."""
    path = tmp_path / "bad.txt"
    path.write_text(_TEXT_DUMP.replace(old, new, 1))
    with pytest.raises(InputError, match=message):
        import_dump(path)


def test_garbage_is_a_malformed_dump(tmp_path: Path) -> None:
    path = tmp_path / "garbage.out"
    path.write_text("hello\nworld\n")
    with pytest.raises(InputError, match="garbage.out: malformed dump"):
        import_dump(path)
