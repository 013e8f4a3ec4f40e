"""Problem sets: a set file's families, dumps, captured scenes and piles become problem files."""

from __future__ import annotations

from pathlib import Path

import pytest

from qpbench.bench import problem_sets
from qpbench.cli import main
from qpbench.errors import InputError, QpbenchError
from qpbench.memory import OutOfMemory
from qpbench.problem import files

PROBLEMS = Path(__file__).resolve().parents[1] / "problems"

SMALL_SET = f"""
[families]
k3 = {{ count = 2 }}

[dumps]
paths = ["{PROBLEMS / "dumps" / "2_balls.json"}"]

[[scenes]]
path = "{PROBLEMS / "scenes" / "ura" / "K3.xml"}"
steps = 5
solver = "clarabel/dual"
"""


def test_a_set_builds_its_families_dumps_and_captured_impacts_once(tmp_path: Path) -> None:
    set_file = tmp_path / "small.toml"
    set_file.write_text(SMALL_SET)
    written = problem_sets.build(set_file, tmp_path / "out")
    assert sorted(path.stem for path in written) == ["2_balls", "K3_step000004", "k3-3-s0",
                                                      "k3-3-s1"]
    captured = files.load(tmp_path / "out" / "K3_step000004.npz")
    assert captured.family == "scene:K3" and captured.reference.verified
    assert problem_sets.build(set_file, tmp_path / "out") == []  # incremental: nothing new


def test_a_scene_glob_captures_every_scene_it_matches(tmp_path: Path) -> None:
    set_file = tmp_path / "grids.toml"
    set_file.write_text(f'[[scenes]]\npath = "{PROBLEMS / "scenes" / "ura" / "grid[35]_itr_0.xml"}"'
                        '\nsteps = 1\nsolver = "clarabel/dual"\n')
    written = problem_sets.build(set_file, tmp_path / "out")
    assert sorted(path.stem for path in written) == ["grid3_itr_0_step000000",
                                                      "grid5_itr_0_step000000"]


def test_a_scene_glob_that_matches_nothing_names_the_entry(tmp_path: Path) -> None:
    set_file = tmp_path / "none.toml"
    set_file.write_text(f'[[scenes]]\npath = "{tmp_path / "nowhere" / "*.xml"}"\n')
    with pytest.raises(InputError, match=r"<scenes\[0\]> attribute 'path': matches no scene"):
        problem_sets.build(set_file, tmp_path / "out")


def test_build_set_prints_what_it_wrote(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    set_file = tmp_path / "small.toml"
    set_file.write_text('[families]\nk4 = { count = 1 }\n')
    assert main(["build-set", str(set_file), "-o", str(tmp_path / "out")]) == 0
    assert f"1 problems written, 1 in {tmp_path / 'out'}" in capsys.readouterr().out


@pytest.mark.parametrize(("text", "message"), [
    ("[families]\nnope = {}\n", r"<families> attribute 'nope': unknown family"),
    ('[[scenes]]\nsteps = 3\n', r"<scenes\[0\]> attribute 'path': missing"),
    ("[families\n", "malformed TOML"),
    ("scenes = " + "[" * 100_000 + "]" * 100_000 + "\n", "nested too deeply"),
    ("[families]\nk4 = 3\n", r"<families> attribute 'k4': must be a table"),
    ("[families]\nk4 = { count = 1.5 }\n",
     r"<families.k4> attribute 'count': must be an integer >= 1, or a list of them"),
    ("[families]\ngrid = { sizes = [3, 4], count = [2] }\n",
     r"<families.grid> attribute 'count': a list of counts needs one count per size"),
    ("[families]\nk4 = { count = [2] }\n",
     r"<families.k4> attribute 'count': a list of counts needs one count per size"),
    ("[families]\ngrid = { sizes = [3], count = [0] }\n",
     r"<families.grid> attribute 'count': must be an integer >= 1, or a list"),
    ("[families]\nbox = { sizes = [-5] }\n", r"<families.box> attribute 'sizes': must be a list"),
    ("[families]\nk4 = { seed = -1 }\n", r"<families.k4> attribute 'seed': must be an integer"),
    # a misspelt or unsupported key is refused, not ignored
    ("[families]\nk4 = { restitution = 0.5 }\n",
     r"<families.k4> attribute 'restitution': unknown key \(known: sizes, count, seed\)"),
    ("[dumps]\npaths = 'dumps/*'\n", r"<dumps> attribute 'paths': must be a list of globs"),
    ("[[scenes]]\npath = 'a.xml'\nsteps = -1\n", r"<scenes\[0\]> attribute 'steps'"),
    ("[[scenes]]\npath = 'a.xml'\nend_time = nan\n", r"<scenes\[0\]> attribute 'end_time'"),
    ("[[scenes]]\npath = 'a.xml'\nmax_problem = 2\n", r"attribute 'max_problem': unknown key"),
    ("[scenes]\npath = 'a.xml'\n", r"<set> attribute 'scenes': must be an array of tables"),
    ("[[piles]]\nbodies = 10\n", r"<piles\[0\]> attribute 'kind': missing"),
    ("[[piles]]\nkind = 'cubes'\nbodies = 10\n",
     r"<piles\[0\]> attribute 'kind': must be one of circles, boxes"),
    ("[[piles]]\nkind = 'boxes'\nbodies = 0\n", r"<piles\[0\]> attribute 'bodies'"),
    ("[[piles]]\nkind = 'boxes'\nbodies = 5\npath = 'a.xml'\n",
     r"<piles\[0\]> attribute 'path': unknown key"),
])
def test_a_bad_set_file_is_one_line_naming_the_entry(tmp_path: Path, text: str,
                                                      message: str) -> None:
    set_file = tmp_path / "bad.toml"
    set_file.write_text(text)
    with pytest.raises(InputError, match=message):
        problem_sets.read_set(set_file)


def test_a_folder_or_a_binary_file_is_no_set_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="cannot read set file"):
        problem_sets.read_set(tmp_path)
    binary = tmp_path / "binary.toml"
    binary.write_bytes(bytes([0xFF, 0xFE, 0xAD]) * 100)
    with pytest.raises(InputError, match=r"binary.toml: cannot read set file"):
        problem_sets.read_set(binary)


def test_a_bad_scene_or_solver_stops_the_build_before_any_output(tmp_path: Path) -> None:
    scene = PROBLEMS / "scenes" / "scisim" / "two_balls.xml"
    set_file = tmp_path / "bad.toml"
    set_file.write_text(f'[[scenes]]\npath = "{scene}"\nsteps = 2\nsolver = "nope"\n')
    with pytest.raises(QpbenchError, match="unknown solver 'nope'"):
        problem_sets.build(set_file, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_a_pile_entry_captures_the_first_impact_of_the_generated_pile(tmp_path: Path) -> None:
    set_file = tmp_path / "piles.toml"
    set_file.write_text('[[piles]]\nkind = "circles"\nbodies = 30\nsolver = "pi-robust"\n')
    written = problem_sets.build(set_file, tmp_path / "out")
    assert [path.stem for path in written] == ["circle_pile_30_step000000"]  # one step
    captured = files.load(written[0])
    assert captured.n_contacts > 30 and captured.reference.verified


def test_a_pile_too_large_for_memory_is_refused_before_it_is_made(tmp_path: Path) -> None:
    set_file = tmp_path / "huge.toml"
    set_file.write_text('[[piles]]\nkind = "boxes"\nbodies = 1000000000000\n')
    with pytest.raises(OutOfMemory, match=r"huge.toml: piles\[0\]: 1000000000000 bodies"):
        problem_sets.build(set_file, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_a_list_of_counts_gives_each_size_its_own(tmp_path: Path) -> None:
    set_file = tmp_path / "counts.toml"
    set_file.write_text("[families]\ngrid = { sizes = [3, 4], count = [3, 1] }\n")
    written = problem_sets.build(set_file, tmp_path / "out")
    assert sorted(path.stem for path in written) == ["grid-3-s0", "grid-3-s1", "grid-3-s2",
                                                      "grid-4-s0"]


def test_a_seed_offset_is_added_to_every_familys_seeds(tmp_path: Path,
                                                        capsys: pytest.CaptureFixture) -> None:
    """The same set file gives fresh problems: seed + offset + i, recorded in each file; dumps
    and scenes are unchanged."""
    set_file = tmp_path / "fresh.toml"
    set_file.write_text('[families]\nk4 = { count = 2, seed = 1 }\n'
                        'grid = { sizes = [3], count = 1 }\n'
                        f'[dumps]\npaths = ["{PROBLEMS / "dumps" / "2_balls.json"}"]\n')
    assert main(["build-set", str(set_file), "--seed-offset", "500", "-o",
                 str(tmp_path / "out")]) == 0
    names = sorted(path.stem for path in files.find([str(tmp_path / "out")]))
    assert names == ["2_balls", "grid-3-s500", "k4-4-s501", "k4-4-s502"]
    assert files.load(tmp_path / "out" / "k4-4-s502.npz").metadata["seed"] == 502
    capsys.readouterr()
    assert main(["build-set", str(set_file), "--seed-offset", "-1", "-o",
                 str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err
    assert "--seed-offset must be at least 0, got -1" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "bad").exists()
