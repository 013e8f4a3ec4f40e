"""Seeded mutations of scene files and problem files, for ``qpbench fuzz``.

A case is fixed by its kind (``scene`` or ``problem``), the run's seed and its number:
:func:`case_rng` seeds a generator from the three, so the same corpus, seed and number give
the same bytes again (a failing case is reproducible without its file).

Scene mutations (:func:`mutate_scene`) act on the parsed tree of a corpus scene: an attribute
set to a value of one of the :data:`BAD_VALUES` categories (NaN, infinity, negative, huge,
tiny, empty, wrong type, overlong) or scaled, an attribute deleted, an element deleted,
duplicated, moved into another element or renamed, and :data:`FEATURES` inserted (every
element of both dialects, friction solvers, boxes, portals and kinematic bodies included,
often with one of their attributes corrupted); or on its bytes: truncated, non-UTF-8 bytes,
control characters, foreign encodings, deep nesting, entity declarations (which defusedxml
must refuse: such a case is ``must_refuse``) and a root of another dialect.

Problem mutations (:func:`mutate_problem`) act on the arrays of a problem file written by
``qpbench.problem.files.save``: values made NaN, infinite, negative, huge or zero, arrays of
another dtype (strings, complex, object arrays stored with pickle) or shape, keys deleted or
added, sparse indices out of range, a header that is not the JSON ``save`` writes, NPY members
that declare sizes far beyond their data or beyond the memory cap; or on the file's bytes:
truncated, flipped, emptied or replaced by other text.
"""

from __future__ import annotations

import copy
import io
import json
import random
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass, field
from typing import Any
from xml.etree.ElementTree import Element

import defusedxml.ElementTree as SafeET
import numpy as np

from qpbench.scenes.parser import KNOWN_ATTRIBUTES, NESTED_ATTRIBUTES

# values an attribute is set to, by category
BAD_VALUES: dict[str, tuple[str, ...]] = {
    "nan": ("nan", "NaN", "-nan", "nan nan", "0 nan"),
    "inf": ("inf", "-inf", "Infinity", "1e309", "-1e400", "inf 0", "0 -inf"),
    "negative": ("-1", "-0.5", "-1e-9", "-0", "-1 -1", "-3", "0 -2", "-1/3"),
    "huge": ("1e300", "1e39", "1e41", "9" * 400, "1e99999", "1e+4000", "-1e300 1e300",
             "2147483648", "99999999999999999999", "1e308 1e308", "123456789/1"),
    "tiny": ("1e-300", "5e-324", "1e-41", "1e-39", "0", "0 0", "1/99999999999999999999",
             "1e-99999", "0.0 0.0"),
    "empty": ("", " ", "\t", "\n"),
    "wrong-type": ("abc", "true", "0x10", "1,5", "1 2 3", "circle", "box", "lcp", "1/0", "0/0",
                   "[1, 2]", "1e", "--1", "1..2", "1_000", "\u0661\u0662", "\u00bd", "0b1",
                   "1.5", "2 ", " 1", "1/2/3", "x y", "none", "normal_and_friction", "grr",
                   "geometric", "symplectic_euler", "stabilized", "ipopt", "ql", "NaN/1"),
    "overlong": ("1" * 100_000, "0." + "1" * 20_000, "a" * 200_000, "1 " * 50_000),
}
SCALES = (-1.0, 0.0, 1e300, 1e-300, 1e20, 1e-20, -1e300)
# (element, attributes known to the parser) covered by a case
Touched = tuple[str, str, str]


@dataclass
class Mutated:
    """One case's input: its bytes, what was done to which base, and whether qpbench must
    refuse it (an entity declaration)."""

    data: bytes
    base: str
    operations: list[str] = field(default_factory=list)
    touched: list[Touched] = field(default_factory=list)
    must_refuse: bool = False


def case_rng(kind: str, seed: int, case: int) -> random.Random:
    """The generator of case ``case`` of ``kind`` in a run seeded ``seed``.

    A string seed is hashed with SHA-512 by :class:`random.Random`, the same in every process.

    Parameters
    ----------
    kind : str
        ``scene`` or ``problem``.
    seed : int
        The run's seed.
    case : int
        The case's number within its kind.

    Returns
    -------
    random.Random
        The case's generator, seeded from ``qpbench-fuzz:KIND:SEED:CASE``.
    """
    return random.Random(f"qpbench-fuzz:{kind}:{seed}:{case}")


# --- scenes --------------------------------------------------------------------------------
def features(dialect: str, planes: int, geometries: int) -> dict[str, str]:
    """XML of every element a ``dialect`` scene may hold, valid as written.

    Parameters
    ----------
    dialect : str
        ``ball2d`` or ``rigidbody2d``.
    planes, geometries : int
        How many static planes and geometries the scene has already (portals and bodies
        index them).

    Returns
    -------
    dict of str to str
        Per feature name, the XML fragment that inserts it.
    """
    staggering = "symplectic_euler" if dialect == "ball2d" else "stabilized"
    common = {
        "static_plane": '<static_plane x="0 -3" n="0 1"/>',
        "planar_portal": (f'<static_plane x="-4 0" n="1 0"/><static_plane x="4 0" n="-1 0"/>'
                          f'<planar_portal planeA="{planes}" planeB="{planes + 1}"/>'),
        "lees_edwards_portal": (f'<static_plane x="0 -4" n="0 1"/><static_plane x="0 4" '
                                f'n="0 -1"/><lees_edwards_portal planeA="{planes}" '
                                f'planeB="{planes + 1}" v="1.0" bounds="3.0"/>'),
        "sobogus_friction_solver": (
            '<sobogus_friction_solver mu="0.5" CoR="0.0" max_iters="50" eval_every="1" '
            f'tol="1.0e-6" staggering="{staggering}" cache_impulses="none" stabilization="1" '
            'penetration_threshold="1.0e-5"/>'),
        "staggered_projections_friction_solver": (
            '<staggered_projections_friction_solver mu="0.3" CoR="0.5" tol="1e-8" '
            'max_iters="20" staggering="geometric" internal_warm_start_alpha="1" '
            'internal_warm_start_beta="1"><lcp_impact_solver name="ql" tol="1e-12"/>'
            '<mdp_friction_solver name="ql" tol="1e-12"/>'
            '</staggered_projections_friction_solver>'),
        "impact_operator": ('<impact_operator type="gr" CoR="0.5" v_tol="1e-9" '
                            'cache_impulses="1"><solver name="policy_iteration" '
                            'max_iters="100" tol="1e-8"/></impact_operator>'),
        "impact_operator_grr": (
            '<impact_operator type="grr" CoR="0.5" v_tol="1e-9" cache_impulses="0">'
            '<elastic_operator type="gr" v_tol="1e-9"><solver name="apgd" tol="1e-7" '
            'max_iters="50"/></elastic_operator><inelastic_operator type="lcp">'
            '<solver name="ql"/></inelastic_operator></impact_operator>'),
        "impact_operator_gauss_seidel": ('<impact_operator type="gauss_seidel" CoR="1" '
                                         'v_tol="1e-9" cache_impulses="0"/>'),
        "integrator": '<integrator type="symplectic_euler" dt="1/1000"/>',
        "end_time": '<end_time t="0.05"/>',
        "scripting": '<scripting callback="insertion_test"/>',
        "camera": '<camera cx="0" cy="0" scale_factor="1" fps="50" render_at_fps="0"/>',
    }
    if dialect == "ball2d":
        return {**common,
                "ball": '<ball x="0.3" y="2" vx="0" vy="-1" m="1" r="0.5" fixed="1"/>',
                "gravity": '<gravity fx="0" fy="-9.81"/>',
                "static_drum": '<static_drum x="0" y="0" r="10"/>'}
    return {**common,
            "geometry_box": (f'<geometry type="box" r="0.5 0.25"/><rigid_body x="0.2 2.5" '
                             f'theta="0.3" v="0 -1" omega="1" rho="2" geo_idx="{geometries}" '
                             'fixed="0"/>'),
            "geometry_circle": (f'<geometry type="circle" r="0.4"/><rigid_body x="-0.3 2.2" '
                                f'theta="0" v="0 -1" omega="0" rho="1" geo_idx="{geometries}" '
                                'fixed="0"/>'),
            "kinematic_body": (f'<geometry type="circle" r="0.5"/><rigid_body x="-2 0" '
                               f'theta="0.1" v="2 0" omega="3" rho="1" geo_idx="{geometries}" '
                               'fixed="1"/>'),
            "near_earth_gravity": '<near_earth_gravity f="0 -9.81"/>'}


FEATURES = tuple(sorted(set(features("ball2d", 0, 0)) | set(features("rigidbody2d", 0, 0))))
_REPLACED_BY = {  # a feature that takes the place of what a scene has one of
    "sobogus_friction_solver": ("impact_operator", "sobogus_friction_solver",
                                "staggered_projections_friction_solver"),
    "integrator": ("integrator",), "end_time": ("end_time",)}
for _name in ("staggered_projections_friction_solver", "impact_operator", "impact_operator_grr",
              "impact_operator_gauss_seidel"):
    _REPLACED_BY[_name] = _REPLACED_BY["sobogus_friction_solver"]

_ENTITY_TRICKS = (
    ('<!DOCTYPE {root} [<!ENTITY one "1.0">]>', 'one'),
    ('<!DOCTYPE {root} [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">'
     '<!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;"><!ENTITY d "&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;">'
     '<!ENTITY e "&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;"><!ENTITY f "&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;">'
     '<!ENTITY g "&f;&f;&f;&f;&f;&f;&f;&f;&f;&f;"><!ENTITY h "&g;&g;&g;&g;&g;&g;&g;&g;&g;&g;">'
     ']>', 'h'),
    ('<!DOCTYPE {root} [<!ENTITY secret SYSTEM "file:///etc/hostname">]>', 'secret'),
    ('<!DOCTYPE {root} [<!ENTITY remote SYSTEM "http://127.0.0.1:9/scene.dtd">]>', 'remote'),
    ('<!DOCTYPE {root} [<!ENTITY % p SYSTEM "file:///etc/hostname"> %p;]>', None),
    ('<!DOCTYPE {root} [<!ENTITY img SYSTEM "x.png" NDATA png><!NOTATION png SYSTEM "p">]>',
     None),
)
_BAD_BYTES = (b"\xff", b"\xfe\xff", b"\xc3\x28", b"\xed\xa0\x80", b"\xf4\x90\x80\x80", b"\x80",
              b"\x00", b"\x01", b"\x1b[2J", b"\xef\xbb\xbf")
_ENCODINGS = ("utf-16", "utf-32", "latin-1", "cp500", "no-such-encoding", "ascii", "utf-7")


def _dialect(root: Element) -> str:
    return "ball2d" if root.tag == "ball2d_scene" else "rigidbody2d"


def _parents(root: Element) -> dict[Element, Element]:
    return {child: parent for parent in root.iter() for child in parent}


def _elements(root: Element) -> list[Element]:
    return [element for element in root.iter() if isinstance(element.tag, str)]


def _known_attributes(dialect: str, tag: str) -> list[str]:
    """The attributes qpbench reads on ``tag`` (empty when it reads any or none)."""
    known = KNOWN_ATTRIBUTES[dialect].get(tag) or NESTED_ATTRIBUTES.get(tag) or frozenset()
    return sorted(known)


def _bad_value(rng: random.Random, current: str | None) -> tuple[str, str]:
    """(category, value): a value of one of the BAD_VALUES categories, or the current value
    with every number in it scaled."""
    if current is not None and rng.random() < 0.2:
        parts = current.split()
        scale = rng.choice(SCALES)
        try:
            return "scaled", " ".join(repr(float(part) * scale) for part in parts)
        except ValueError:
            pass
    category = rng.choice(sorted(BAD_VALUES))
    return category, rng.choice(BAD_VALUES[category])


def _set_attribute(rng: random.Random, root: Element, element: Element, out: Mutated) -> None:
    dialect = _dialect(root)
    names = sorted(set(element.attrib) | set(_known_attributes(dialect, element.tag)))
    if not names:
        names = ["qpbench_unknown"]
    name = rng.choice(names)
    category, value = _bad_value(rng, element.get(name))
    element.set(name, value)
    out.operations.append(f"set <{element.tag}> '{name}' to {category} {value[:24]!r}")
    out.touched.append((dialect, element.tag, name))


def _delete_attribute(rng: random.Random, root: Element, element: Element, out: Mutated) -> None:
    if not element.attrib:
        return _set_attribute(rng, root, element, out)
    name = rng.choice(sorted(element.attrib))
    del element.attrib[name]
    out.operations.append(f"delete <{element.tag}> '{name}'")
    out.touched.append((_dialect(root), element.tag, name))
    return None


def _insert_feature(rng: random.Random, root: Element, out: Mutated) -> Element:
    """Inserts one of the dialect's features (replacing what a scene has only one of) and
    returns its last element."""
    dialect = _dialect(root)
    planes = len(root.findall("static_plane"))
    geometries = len(root.findall("geometry"))
    available = features(dialect, planes, geometries)
    name = rng.choice(sorted(available))
    for tag in _REPLACED_BY.get(name, ()):
        for element in root.findall(tag):
            root.remove(element)
    inserted = list(SafeET.fromstring(f"<group>{available[name]}</group>"))
    position = rng.randint(0, len(root))
    for offset, element in enumerate(inserted):
        root.insert(position + offset, element)
    out.operations.append(f"insert {name}")
    return inserted[-1]


def _element_operation(rng: random.Random, root: Element, out: Mutated) -> None:
    """Deletes, duplicates, moves or renames an element (never the root)."""
    parents = _parents(root)
    children = [element for element in _elements(root) if element in parents]
    if not children:
        return
    element = rng.choice(children)
    parent = parents[element]
    operation = rng.choice(("delete", "duplicate", "duplicate", "move", "rename"))
    if operation == "delete":
        parent.remove(element)
    elif operation == "duplicate":
        copies = rng.choice((1, 1, 2, 5, 40))
        index = list(parent).index(element)
        for _ in range(copies):
            parent.insert(index + 1, copy.deepcopy(element))
        operation = f"duplicate x{copies}"
    elif operation == "move":
        inside = set(element.iter())
        targets = [target for target in _elements(root)
                   if target not in inside and target is not parent]
        if not targets:
            return
        target = rng.choice(targets)
        parent.remove(element)
        target.append(element)
        operation = f"move into <{target.tag}>"
    else:
        new_tag = rng.choice((element.tag.upper(), element.tag + "s", "ns:" + element.tag,
                              rng.choice(FEATURES).removesuffix("_grr"), "ball", "rigid_body",
                              "geometry", "solver"))
        operation = f"rename to <{new_tag}>"
        element.tag = new_tag.replace("ns:", "{urn:qpbench-fuzz}")
    out.operations.append(f"{operation} <{element.tag}>")


def _serialize(root: Element) -> bytes:
    return ET.tostring(root, encoding="utf-8")


def _byte_operation(rng: random.Random, data: bytes, root_tag: str, out: Mutated) -> bytes:
    """A mutation of the serialized scene's bytes."""
    operation = rng.choice(("truncate", "bad_bytes", "encoding", "deep_nesting", "entity",
                            "flip", "root", "grr_chain", "many_attributes", "empty"))
    out.operations.append(operation)
    if operation == "truncate":
        return data[:rng.randint(0, max(len(data) - 1, 0))]
    if operation == "bad_bytes":
        at = rng.randint(0, len(data))
        return data[:at] + rng.choice(_BAD_BYTES) * rng.choice((1, 3)) + data[at:]
    if operation == "encoding":
        encoding = rng.choice(_ENCODINGS)
        text = data.decode("utf-8", errors="replace")
        declaration = f'<?xml version="1.0" encoding="{encoding}"?>\n'
        if rng.random() < 0.5:
            try:
                return (declaration + text).encode(encoding)
            except (LookupError, UnicodeError):
                pass
        return declaration.encode() + data
    if operation == "deep_nesting":
        depth = rng.choice((100, 1000, 20_000, 200_000))
        tag = rng.choice(("x", "impact_operator", "elastic_operator", "solver", "ball"))
        nested = f"<{tag}>" * depth + f"</{tag}>" * depth
        at = data.find(b">", data.find(f"<{root_tag}".encode())) + 1
        return data[:at] + nested.encode() + data[at:]
    if operation == "grr_chain":  # a grr whose elastic operator is a grr, and so on
        depth = rng.choice((3, 60, 2000, 20_000))
        chain = ('<elastic_operator type="grr">' * depth + '</elastic_operator>' * depth)
        operator = (f'<impact_operator type="grr" CoR="0.5">{chain}<inelastic_operator '
                    'type="lcp"><solver name="ql"/></inelastic_operator></impact_operator>')
        text = data.decode("utf-8", errors="replace")
        start, end = text.find("<impact_operator"), text.find("</impact_operator>")
        if start >= 0 and end > start:
            text = text[:start] + text[end + len("</impact_operator>"):]
        at = text.find(">", text.find(f"<{root_tag}")) + 1
        return (text[:at] + operator + text[at:]).encode()
    if operation == "entity":
        template, name = rng.choice(_ENTITY_TRICKS)
        out.must_refuse = True
        text = data.decode("utf-8", errors="replace")
        if name is not None:
            text = text.replace('"', f'"&{name};', 1) if rng.random() < 0.5 else text.replace(
                f"<{root_tag}>", f"<{root_tag}>&{name};", 1)
        return (template.format(root=root_tag) + "\n" + text).encode()
    if operation == "flip":
        flipped = bytearray(data)
        for _ in range(rng.choice((1, 4, 32))):
            if flipped:
                flipped[rng.randrange(len(flipped))] = rng.randrange(256)
        return bytes(flipped)
    if operation == "root":
        other = rng.choice(("ball2d_scene", "rigidbody2d_scene", "ball3d_scene", "scene",
                            "rigidbody3d_scene", "_scene"))
        text = data.decode("utf-8", errors="replace")
        return text.replace(f"<{root_tag}", f"<{other}", 1).replace(
            f"</{root_tag}>", f"</{other}>").encode()
    if operation == "many_attributes":
        attributes = " ".join(f'a{index}="{index}"' for index in range(rng.choice((50, 20_000))))
        return data.replace(b"<ball ", f"<ball {attributes} ".encode(), 1).replace(
            b"<rigid_body ", f"<rigid_body {attributes} ".encode(), 1)
    return b""


def mutate_scene(corpus: list[tuple[str, bytes]], rng: random.Random) -> Mutated:
    """One scene case: a corpus scene with one to three mutations (see the module docstring).

    Tree mutations come first, then at most one of the bytes.

    Parameters
    ----------
    corpus : list of (str, bytes)
        The scenes to mutate, each a name and its XML.
    rng : random.Random
        The case's generator (:func:`case_rng`).

    Returns
    -------
    Mutated
        The case's bytes, its base scene, the operations done and the attributes touched.
    """
    base, text = rng.choice(corpus)
    out = Mutated(data=b"", base=base)
    root = SafeET.fromstring(text)
    for _ in range(rng.choice((1, 1, 2, 3))):
        choice = rng.random()
        elements = _elements(root)
        if choice < 0.35:
            _set_attribute(rng, root, rng.choice(elements), out)
        elif choice < 0.45:
            _delete_attribute(rng, root, rng.choice(elements), out)
        elif choice < 0.7:
            inserted = _insert_feature(rng, root, out)
            if rng.random() < 0.7:
                (_set_attribute if rng.random() < 0.8 else _delete_attribute)(
                    rng, root, rng.choice([inserted, *list(inserted.iter())]), out)
        elif choice < 0.85:
            _element_operation(rng, root, out)
        else:
            out.data = _byte_operation(rng, _serialize(root), root.tag, out)
            return out
    out.data = _serialize(root)
    return out


# --- problems ------------------------------------------------------------------------------
_DTYPES = ("int8", "int64", "uint8", "float16", "float32", ">f8", "complex128", "bool", "<U8",
           "S8", "datetime64[s]", "object", "structured")
_HEADER_VALUES: tuple[Any, ...] = (None, True, -1, 0, 3, 10**18, 1.5, float("nan"), "",
                                   "x" * 1000, [], {}, ["nonexistent"], {"a": 1})


def _npy_member(shape: tuple[int, ...], dtype: str, payload: bytes) -> bytes:
    """The bytes of an NPY file whose header declares ``shape`` and ``dtype`` followed by
    ``payload`` (whatever its length)."""
    stream = io.BytesIO()
    header = {"descr": np.dtype(dtype).str, "fortran_order": False, "shape": shape}
    np.lib.format.write_array_header_1_0(stream, header)
    return stream.getvalue() + payload


def _zip(members: dict[str, bytes]) -> bytes:
    stream = io.BytesIO()
    with zipfile.ZipFile(stream, "w") as archive:
        for name, payload in members.items():
            archive.writestr(name, payload)
    return stream.getvalue()


def _npz(arrays: dict[str, np.ndarray]) -> bytes:
    """An ``.npz`` of ``arrays`` (object arrays pickled, as ``np.savez`` stores them)."""
    return _zip({f"{key}.npy": value for key, value in _npz_members(arrays).items()})


def _retyped(rng: random.Random, value: np.ndarray) -> np.ndarray:
    dtype = rng.choice(_DTYPES)
    if dtype == "object":
        return np.array([*value.ravel()[:3].tolist(), "x", None], dtype=object)
    if dtype == "structured":
        return np.zeros(value.shape, dtype=[("a", "f8"), ("b", "i4")])
    if dtype == "datetime64[s]":
        return np.zeros(value.shape, dtype=dtype)
    with np.errstate(all="ignore"):
        try:
            return value.astype(dtype)
        except (TypeError, ValueError, OverflowError):
            return np.zeros(value.shape, dtype=dtype)


def _as_integers(value: np.ndarray) -> np.ndarray:
    """``value`` flattened as int64, zeros where it holds no numbers (an earlier mutation of
    the same case may have made it objects, strings, records or dates)."""
    if value.dtype.kind not in "biuf":
        return np.zeros(value.size, dtype=np.int64)
    with np.errstate(all="ignore"):
        return value.ravel().astype(np.int64)


def _reshaped(rng: random.Random, value: np.ndarray) -> np.ndarray:
    flat = value.ravel()
    choice = rng.choice(("column", "row", "shorter", "longer", "empty", "scalar", "cube"))
    if choice == "column":
        return flat.reshape(-1, 1)
    if choice == "row":
        return flat.reshape(1, -1)
    if choice == "shorter":
        return flat[:max(flat.size - rng.choice((1, 2)), 0)]
    if choice == "longer":
        return np.concatenate([flat, flat[:1] if flat.size else np.zeros(1, flat.dtype)])
    if choice == "empty":
        return flat[:0]
    if choice == "scalar":
        return np.asarray(flat[0] if flat.size else 0)
    return np.zeros((2, 2, 2), dtype=flat.dtype)


def _revalued(rng: random.Random, value: np.ndarray) -> tuple[np.ndarray, str]:
    """``value`` with entries made NaN, infinite, negative, huge, zero or out of range."""
    changed = value.copy()
    if changed.size == 0:
        return np.zeros(3, dtype=value.dtype), "filled"
    count = rng.choice((1, 1, changed.size))
    where = [rng.randrange(changed.size) for _ in range(count)]
    flat = changed.reshape(-1)
    if changed.dtype.kind in "iu":
        replacement = rng.choice((-1, -(2**31), 2**31 - 1, 0, 10**9))
        if changed.dtype.kind == "u" and replacement < 0:
            replacement = int(np.iinfo(changed.dtype).max)
        with np.errstate(all="ignore"):
            flat[where] = np.array(replacement).astype(changed.dtype)
        return changed, f"integer {replacement}"
    if changed.dtype.kind != "f":
        return changed, "unchanged"
    replacement = rng.choice((np.nan, np.inf, -np.inf, -1.0, 1e308, 1e-308, 0.0, -1e300, 5e-324))
    flat[where] = replacement
    return changed, f"{replacement!r}"


def _header_mutation(rng: random.Random, header: dict[str, Any]) -> tuple[bytes, str]:
    """Header bytes that are not the JSON ``save`` writes, and what was done."""
    choice = rng.choice(("field", "field", "delete", "nested", "not_json", "not_utf8",
                         "not_object", "reference"))
    header = copy.deepcopy(header)
    if choice in ("field", "delete"):
        key = rng.choice(sorted({*header, "format", "kind", "name", "dofs_per_body", "data",
                                 "metadata", "reference", "frictional_reference"}))
        if choice == "delete":
            header.pop(key, None)
            return json.dumps(header).encode(), f"header delete {key!r}"
        header[key] = rng.choice(_HEADER_VALUES)
        return json.dumps(header).encode(), f"header {key!r} = {header[key]!r:.30}"
    if choice == "reference":
        for name in ("reference", "frictional_reference"):
            if isinstance(header.get(name), dict) and header[name]:
                field_name = rng.choice(sorted(header[name]))
                header[name][field_name] = rng.choice(_HEADER_VALUES)
                return json.dumps(header).encode(), f"header {name}.{field_name}"
        return json.dumps(header).encode(), "header unchanged"
    if choice == "nested":
        depth = rng.choice((100, 100_000))
        return (b'{"format": 2, "name": "x", "metadata": ' + b"[" * depth + b"]" * depth
                + b"}"), f"header nested {depth}"
    if choice == "not_json":
        text = json.dumps(header).encode()
        return text[:rng.randint(0, len(text))] + rng.choice((b"", b"}", b"\x00")), "header cut"
    if choice == "not_utf8":
        return b'{"format": 2, "name": "\xff\xfe"}', "header not UTF-8"
    return rng.choice((b"[1, 2]", b"2", b'"name"', b"null")), "header not an object"


def mutate_problem(corpus: list[tuple[str, bytes]], rng: random.Random,
                   memory_limit_mb: int) -> Mutated:
    """One problem case: a corpus problem file with one or two mutations (see the module docstring).

    Parameters
    ----------
    corpus : list of (str, bytes)
        The problem files to mutate, each a name and its bytes.
    rng : random.Random
        The case's generator (:func:`case_rng`).
    memory_limit_mb : int
        The case's address-space cap in MiB: it sizes the NPY members declared just beyond it.

    Returns
    -------
    Mutated
        The case's bytes, its base file and the operations done.
    """
    base, data = rng.choice(corpus)
    out = Mutated(data=data, base=base)
    with np.load(io.BytesIO(data), allow_pickle=False) as archive:
        arrays = {key: archive[key] for key in archive.files}
    header = json.loads(arrays["header_json"].tobytes())
    raw_members: dict[str, bytes] = {}
    for _ in range(rng.choice((1, 1, 2))):
        key = rng.choice(sorted(arrays))
        choice = rng.choice(("values", "values", "dtype", "shape", "delete", "extra", "header",
                             "declared_size", "sparse", "bytes"))
        if choice == "values" and key != "header_json":
            arrays[key], what = _revalued(rng, arrays[key])
            out.operations.append(f"{key} {what}")
        elif choice == "dtype":
            arrays[key] = _retyped(rng, arrays[key])
            out.operations.append(f"{key} as {arrays[key].dtype}")
        elif choice == "shape":
            arrays[key] = _reshaped(rng, arrays[key])
            out.operations.append(f"{key} shape {arrays[key].shape}")
        elif choice == "delete":
            arrays.pop(key)
            out.operations.append(f"delete {key}")
        elif choice == "extra":
            name = rng.choice(("data_extra", "ref_extra", "G_extra", "header_json2"))
            arrays[name] = np.arange(3.0)
            if rng.random() < 0.5 and isinstance(header, dict):
                header.setdefault("data", []).append(name.removeprefix("data_"))
                arrays["header_json"] = np.frombuffer(json.dumps(header).encode(), np.uint8)
            out.operations.append(f"extra {name}")
        elif choice == "header" or key == "header_json":
            text, what = _header_mutation(rng, header if isinstance(header, dict) else {})
            arrays["header_json"] = np.frombuffer(text, dtype=np.uint8)
            out.operations.append(what)
        elif choice == "declared_size":
            beyond_cap = (memory_limit_mb + 256) * 1024 * 1024 // 8
            shape = rng.choice(((2**40,), (beyond_cap,), (2**62, 2**62), (beyond_cap, 0)))
            raw_members[key] = _npy_member(shape, "<f8", b"\x00" * 64)
            out.operations.append(f"{key} declares shape {shape}")
        elif choice == "sparse":
            label = rng.choice([name for name in ("G", "T") if f"{name}_shape" in arrays] or ["G"])
            part = rng.choice(("shape", "indices", "indptr"))
            values = rng.choice(((2**40, 2**40), (2**31, 3), (-1, 3), (0, 0), (10**12, 1),
                                 (3, 2**33)))
            if part == "shape":
                arrays[f"{label}_shape"] = np.array(values, dtype=np.int64)
            elif f"{label}_{part}" in arrays and arrays[f"{label}_{part}"].size:
                changed = _as_integers(arrays[f"{label}_{part}"])
                changed[rng.randrange(changed.size)] = values[0]
                arrays[f"{label}_{part}"] = changed
            out.operations.append(f"{label}_{part} {values}")
        else:
            out.operations.append("file bytes")
            out.data = _problem_bytes(rng, _npz(arrays) if out.operations[:-1] else data, out)
            return out
    members = {**_npz_members(arrays), **raw_members}
    out.data = _zip({f"{key}.npy": value for key, value in members.items()})
    return out


def _npz_members(arrays: dict[str, np.ndarray]) -> dict[str, bytes]:
    members = {}
    for key, value in arrays.items():
        stream = io.BytesIO()
        np.save(stream, value, allow_pickle=True)
        members[key] = stream.getvalue()
    return members


def _problem_bytes(rng: random.Random, data: bytes, out: Mutated) -> bytes:
    """A mutation of a problem file's bytes."""
    choice = rng.choice(("truncate", "flip", "empty", "text", "garbage_member", "nested_zip"))
    out.operations[-1] = f"file {choice}"
    if choice == "truncate":
        return data[:rng.randint(0, max(len(data) - 1, 0))]
    if choice == "flip":
        flipped = bytearray(data)
        for _ in range(rng.choice((1, 8))):
            flipped[rng.randrange(len(flipped))] = rng.randrange(256)
        return bytes(flipped)
    if choice == "empty":
        return b""
    if choice == "text":
        return rng.choice((b"<ball2d_scene/>", b"PK\x03\x04", b"\x93NUMPY", b"{}", b"\xff" * 99))
    if choice == "garbage_member":
        return _zip({"m_inv.npy": b"\x93NUMPY\x01\x00garbage", "header_json.npy": b"x"})
    return _zip({"inner.npz": data})
