"""Reads SCISim's ``<ball2d_scene>`` and ``<rigidbody2d_scene>`` files as they are.

XML is parsed with defusedxml, so entity declarations (billion-laughs bombs) and
external references are refused. Every fault in the input is one
:class:`~qpbench.errors.InputError` naming the file, the element and the
attribute; a feature qpbench does not simulate (portals in a scene with boxes) is an
:class:`~qpbench.errors.UnsupportedError`. Friction solvers are checked by SCISim's own
rules (``Ball2DSceneParser.cpp::loadSobogusFrictionSolver`` and its rigidbody2d analogue).
Unknown elements and attributes are accepted, as SCISim does, and named once in ``Scene.warnings``.
A ``<scripting callback>`` is never run.
"""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from fractions import Fraction
from pathlib import Path
from xml.etree.ElementTree import Element

import defusedxml
import defusedxml.ElementTree as SafeET
import numpy as np

from qpbench.errors import MAX_QUOTED, InputError, UnsupportedError, shown
from qpbench.scenes.model import (
    CACHE_MODES,
    INTEGRATORS,
    OPERATORS,
    STAGGERINGS,
    Bodies,
    FrictionSolver,
    ImpactOperator,
    Portal,
    Scene,
    SolverChoice,
)
from qpbench.scenes.solver_names import SCISIM_TO_QPBENCH, qpbench_name

MAX_SCENE_BYTES = 256 * 1024 * 1024
# the magnitudes qpbench reads: every real attribute lies in [-LARGEST, LARGEST], and a positive
# one (a mass, a radius, a density, a time step) is at least 1 / LARGEST. Energies, inertias
# and squared distances are products of up to seven of them (rho r^4 omega^2 for a circle), so
# they stay inside floating-point range (about 1e308) instead of overflowing to inf.
LARGEST = 1e40
# a decimal as Fraction reads it; qpbench reads exponents of at most MAX_EXPONENT_DIGITS digits
_DECIMAL = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?(?P<exponent>\d+))?")
MAX_EXPONENT_DIGITS = 4
# integers (indices, iteration counts) qpbench reads have at most this magnitude
LARGEST_INTEGER = 2**53
# a warning names at most MAX_NAMED unknown elements and attributes
MAX_NAMED = 10

# Known attributes of every top-level element qpbench reads, per dialect (``None``: any
# attribute is fine).
_COMMON: dict[str, frozenset[str] | None] = {
    "camera": None,
    "integrator": frozenset({"type", "dt"}),
    "impact_operator": frozenset({"type", "CoR", "v_tol", "cache_impulses"}),
    "end_time": frozenset({"t"}),
    "static_plane": frozenset({"x", "n"}),
    "scripting": frozenset({"callback"}),
    "planar_portal": frozenset({"planeA", "planeB"}),
    "lees_edwards_portal": frozenset({"planeA", "planeB", "v", "bounds"}),
    "sobogus_friction_solver": frozenset({
        "mu", "CoR", "max_iters", "eval_every", "tol", "cache_impulses", "staggering",
        "stabilization", "penetration_threshold"}),
    "staggered_projections_friction_solver": frozenset({
        "mu", "CoR", "tol", "max_iters", "staggering", "internal_warm_start_alpha",
        "internal_warm_start_beta"}),
}
_SP_CHILDREN = frozenset({"lcp_impact_solver", "mdp_friction_solver"})
KNOWN_ATTRIBUTES: dict[str, dict[str, frozenset[str] | None]] = {
    "ball2d": {
        **_COMMON,
        "ball": frozenset({"x", "y", "vx", "vy", "m", "r", "fixed"}),
        "gravity": frozenset({"fx", "fy"}),
        "static_drum": frozenset({"x", "y", "r"}),
    },
    "rigidbody2d": {
        **_COMMON,
        "geometry": frozenset({"type", "r"}),
        "rigid_body": frozenset({"x", "theta", "v", "omega", "rho", "geo_idx", "fixed"}),
        "near_earth_gravity": frozenset({"f"}),
    },
}
_OPERATOR_CHILDREN = frozenset({"solver", "elastic_operator", "inelastic_operator"})
# Attributes qpbench reads on the elements nested in an operator or a friction solver (a
# ``<solver>``'s other attributes are its options, kept as text).
NESTED_ATTRIBUTES: dict[str, frozenset[str]] = {
    "solver": frozenset({"name"}),
    "lcp_impact_solver": frozenset({"name"}),
    "mdp_friction_solver": frozenset({"name"}),
    "elastic_operator": frozenset({"type", "CoR", "v_tol", "cache_impulses"}),
    "inelastic_operator": frozenset({"type", "CoR", "v_tol", "cache_impulses"}),
}
_SINGLETONS = ("integrator", "impact_operator", "end_time")
_FRICTION_SOLVERS = ("sobogus_friction_solver", "staggered_projections_friction_solver")
_PORTALS = ("planar_portal", "lees_edwards_portal")


def _cut(name: str) -> str:
    """A name from the scene (a tag) cut to MAX_QUOTED characters."""
    return name if len(name) <= MAX_QUOTED else f"{name[:MAX_QUOTED]}..."


def _named(names: list[str]) -> str:
    """At most MAX_NAMED of ``names``, each cut to MAX_QUOTED characters, and how many more."""
    listed = ", ".join(_cut(name) for name in names[:MAX_NAMED])
    return listed + (f" and {len(names) - MAX_NAMED} more" if len(names) > MAX_NAMED else "")


def _child_tags(root: Element) -> set[str]:
    """Tags of the root's children."""
    return {child.tag for child in root if isinstance(child.tag, str)}


class _Reader:
    """Reads typed attributes of elements; every fault names file, element and attribute."""

    def __init__(self, path: str) -> None:
        self.path = path
        self.unknown: list[str] = []

    def error(self, element: Element, attribute: str | None, message: str,
              index: int | None = None) -> InputError:
        where = f" ({element.tag} #{index})" if index is not None else ""
        return InputError(self.path, message + where, element=element.tag, attribute=attribute)

    def note_unknown(self, element: Element, known: frozenset[str] | None) -> None:
        if known is None:
            return
        for name in element.attrib:
            if name not in known:
                self.unknown.append(f"<{element.tag}> '{name}'")

    def text(self, element: Element, name: str, index: int | None = None) -> str:
        value = element.get(name)
        if value is None:
            raise self.error(element, name, "missing", index)
        return value

    def number(self, element: Element, name: str, index: int | None = None,
               default: float | None = None, check: str | None = None) -> float:
        """A finite float; ``check`` is ``positive``, ``nonnegative`` or ``unit`` ([0, 1])."""
        if default is not None and element.get(name) is None:
            return default
        raw = self.text(element, name, index)
        try:
            value = float(raw)
        except ValueError:
            raise self.error(element, name, f"not a number: {shown(raw)}", index) from None
        if not math.isfinite(value):
            raise self.error(element, name, f"must be finite, got {shown(raw)}", index)
        self._check(element, name, value, raw, check, index)
        self._check_range(element, name, np.array([value]), raw, check == "positive", index)
        return value

    def _check_range(self, element: Element, name: str, values: np.ndarray, raw: str,
                     positive: bool, index: int | None) -> None:
        """Every ``|value| <= LARGEST``, and ``>= 1 / LARGEST`` when ``positive``."""
        magnitude = np.abs(values)
        if np.any(magnitude > LARGEST) or (positive and np.any(magnitude < 1.0 / LARGEST)):
            raise self._out_of_range(element, name, raw, positive, index)

    def _out_of_range(self, element: Element, name: str, raw: str, positive: bool,
                      index: int | None) -> InputError:
        smallest = f", positive values from {1.0 / LARGEST:g}" if positive else ""
        return self.error(element, name, f"out of range: {shown(raw)} (qpbench reads magnitudes up "
                                         f"to {LARGEST:g}{smallest})", index)

    def _check(self, element: Element, name: str, value: float, raw: str, check: str | None,
               index: int | None) -> None:
        if check == "positive" and not value > 0:
            raise self.error(element, name, f"must be positive, got {shown(raw)}", index)
        if check == "nonnegative" and not value >= 0:
            raise self.error(element, name, f"must be >= 0, got {shown(raw)}", index)
        if check == "unit" and not 0 <= value <= 1:
            raise self.error(element, name, f"must lie in [0, 1], got {shown(raw)}", index)

    def vector(self, element: Element, name: str, index: int | None = None,
               positive: bool = False) -> np.ndarray:
        """Two finite floats separated by white space: ``x="0.5 -1"``; both > 0 when
        ``positive``."""
        raw = self.text(element, name, index)
        parts = raw.split()
        if len(parts) != 2:
            raise self.error(element, name, f"expected two numbers, got {shown(raw)}", index)
        try:
            values = np.array([float(part) for part in parts])
        except ValueError:
            raise self.error(element, name, f"not two numbers: {shown(raw)}", index) from None
        if not np.all(np.isfinite(values)):
            raise self.error(element, name, f"must be finite, got {shown(raw)}", index)
        if positive and not np.all(values > 0):
            raise self.error(element, name, f"must be positive, got {shown(raw.strip())}", index)
        self._check_range(element, name, values, raw, positive, index)
        return values

    def boolean(self, element: Element, name: str, index: int | None = None,
                default: bool | None = None) -> bool:
        """SCISim's booleans: ``0`` or ``1``."""
        if default is not None and element.get(name) is None:
            return default
        raw = self.text(element, name, index).strip()
        if raw not in ("0", "1"):
            raise self.error(element, name, f"must be 0 or 1, got {shown(raw)}", index)
        return raw == "1"

    def integer(self, element: Element, name: str, index: int | None = None,
                check: str | None = None) -> int:
        """An integer; ``check`` is ``positive`` or None."""
        raw = self.text(element, name, index)
        try:
            value = int(raw.strip())
        except ValueError:
            raise self.error(element, name, f"not an integer: {shown(raw)}", index) from None
        if abs(value) > LARGEST_INTEGER:
            raise self.error(element, name, f"out of range: {shown(raw)} (qpbench reads "
                             f"integers up to {LARGEST_INTEGER})", index)
        if check == "positive" and not value > 0:
            raise self.error(element, name, f"must be a positive integer, got {shown(raw)}", index)
        return value

    def choice(self, element: Element, name: str, options: tuple[str, ...]) -> str:
        """One of ``options``, spelled exactly."""
        raw = self.text(element, name)
        if raw.strip() not in options:
            raise self.error(element, name,
                             f"must be one of {', '.join(options)}, got {shown(raw)}")
        return raw.strip()

    def fraction(self, element: Element, name: str, index: int | None = None) -> Fraction:
        """A positive exact rational from a decimal (``0.01``, an exponent of at most four
        digits: Fraction builds 10^exponent exactly) or a fraction (``1/10080``), within
        [1 / LARGEST, LARGEST]."""
        raw = self.text(element, name, index)
        text = raw.strip()
        try:
            if "/" in text:
                numerator, denominator = text.split("/", 1)
                value = Fraction(int(numerator), int(denominator))
            elif decimal := _DECIMAL.fullmatch(text):
                if len(decimal["exponent"] or "") > MAX_EXPONENT_DIGITS:
                    raise self.error(element, name, "out of range: an exponent of more than "
                                     f"four digits, {raw[:40]!r}", index)
                value = Fraction(text)
            else:
                raise ValueError(text)
        except (ValueError, ZeroDivisionError):
            raise self.error(element, name, f"not a decimal or a fraction: {shown(raw)}",
                             index) from None
        if not value > 0:
            raise self.error(element, name, f"must be positive, got {shown(raw)}", index)
        if not 1.0 / LARGEST <= value <= LARGEST:  # compared exactly
            raise self._out_of_range(element, name, raw, True, index)
        return value


def load_scene(path: str | os.PathLike[str]) -> Scene:
    """Reads and parses the scene file at ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        The SCISim XML file, at most MAX_SCENE_BYTES long.

    Returns
    -------
    Scene
        The scene, as :func:`parse_scene` gives it.

    Raises
    ------
    InputError
        When the file is missing, a folder, too large, unreadable or bad input.
    UnsupportedError
        When it asks for something qpbench does not simulate.
    """
    path = Path(path)
    try:
        size = path.stat().st_size
        if size > MAX_SCENE_BYTES:
            raise InputError(str(path), f"scene file too large ({size} bytes)")
        data = path.read_bytes()
    except FileNotFoundError:
        raise InputError(str(path), "no such scene file") from None
    except IsADirectoryError:
        raise InputError(str(path), "is a folder, not a scene file") from None
    except OSError as error:
        raise InputError(str(path), f"cannot read scene file ({error.strerror})") from None
    return parse_scene(data, str(path))


def parse_scene(data: bytes | str, path: str = "<scene>") -> Scene:
    """Parses the text of a scene file; ``path`` names it in messages.

    Parameters
    ----------
    data : bytes or str
        The XML text (a str is encoded as UTF-8).
    path : str, optional
        The file named in messages and kept as the scene's path; ``<scene>`` by default.

    Returns
    -------
    Scene
        The scene of a ``<ball2d_scene>`` or ``<rigidbody2d_scene>``.

    Raises
    ------
    InputError
        When the XML is malformed or refused, not a SCISim 2D scene, or an element or
        attribute is invalid.
    UnsupportedError
        When the scene asks for something qpbench does not simulate.
    """
    if isinstance(data, str):
        data = data.encode("utf-8")
    try:
        root = SafeET.fromstring(data)
    except defusedxml.DefusedXmlException as error:
        raise InputError(path, f"refused: {error} (entity declarations and external "
                               "references are not allowed)") from None
    except (ET.ParseError, ValueError, LookupError) as error:  # LookupError: an encoding
        raise InputError(path, f"malformed XML: {error}") from None  # without a codec
    dialect = root.tag.removesuffix("_scene") if root.tag.endswith("_scene") else ""
    if dialect not in KNOWN_ATTRIBUTES:
        if root.tag.endswith("_scene"):
            raise UnsupportedError(f"{path}: <{_cut(root.tag)}>: not supported: qpbench reads "
                                   "<ball2d_scene> and <rigidbody2d_scene>")
        raise InputError(path, "not a SCISim 2D scene (expected <ball2d_scene> or "
                               "<rigidbody2d_scene>)", element=_cut(root.tag))
    reader = _Reader(path)
    known = KNOWN_ATTRIBUTES[dialect]
    unknown_elements: list[str] = []
    children: dict[str, list[Element]] = {}
    for child in root:
        if not isinstance(child.tag, str):
            continue
        if child.tag not in known:
            unknown_elements.append(f"<{child.tag}>")
            continue
        reader.note_unknown(child, known[child.tag])
        children.setdefault(child.tag, []).append(child)
    for tag in _SINGLETONS:
        if len(children.get(tag, [])) > 1:
            raise InputError(path, f"appears {len(children[tag])} times; a scene has one",
                             element=tag)

    warnings: list[str] = []
    if dialect == "ball2d":
        bodies = _ball2d_bodies(reader, children, warnings)
    else:
        bodies = _rigidbody2d_bodies(reader, children, warnings)
    integrator, dt = _integrator(reader, children)
    scene = Scene(path=path, dialect=dialect, bodies=bodies, integrator=integrator, dt=dt)
    scene.gravity = _gravity(reader, children, dialect)
    scene.plane_points, scene.plane_normals = _planes(reader, children)
    scene.portals, scene.plane_points, scene.plane_normals = _portals(
        reader, children, scene.plane_points, scene.plane_normals)
    if scene.portals and bodies.has_boxes:
        raise UnsupportedError(f"{path}: <planar_portal>/<lees_edwards_portal>: not supported "
                               "with box geometry: qpbench finds contacts across portals for "
                               "circles only (SCISim stops on a box crossing one too)")
    if dialect == "ball2d":
        scene.drum_centers, scene.drum_radii = _drums(reader, children)
    scene.impact, scene.friction = _impact(reader, children, dialect)
    if "end_time" in children:
        scene.end_time = reader.fraction(children["end_time"][0], "t")
    for script in children.get("scripting", []):
        callback = shown(script.get("callback", ""))
        warnings.append(f"{path}: <scripting callback={callback}> ignored: qpbench never runs "
                        "code named by a scene")
    unknown = sorted(set(unknown_elements)) + sorted(set(reader.unknown))
    if unknown:
        warnings.insert(0, f"{path}: ignoring what qpbench does not know: {_named(unknown)}")
    scene.warnings = warnings
    return scene


def _ball2d_bodies(reader: _Reader, children: dict[str, list[Element]],
                   warnings: list[str]) -> Bodies:
    """``<ball x y vx vy m r fixed/>``, mass given. ``fixed`` is required and checked, and
    then has no effect, as in SCISim: its ball2d stores the flag, but no ball is kinematically
    scripted there (``Ball2DSim::isKinematicallyScripted`` is false), so a fixed ball moves,
    feels gravity and takes impulses with its own mass like any other. Said once in
    ``warnings``."""
    rows = []
    declared_fixed = []
    for index, ball in enumerate(children.get("ball", [])):
        rows.append((
            reader.number(ball, "x", index), reader.number(ball, "y", index),
            reader.number(ball, "vx", index), reader.number(ball, "vy", index),
            reader.number(ball, "m", index, check="positive"),
            reader.number(ball, "r", index, check="positive"),
        ))
        if reader.boolean(ball, "fixed", index):
            declared_fixed.append(index)
    if declared_fixed:
        shown = ", ".join(str(index) for index in declared_fixed[:10])
        more = f" and {len(declared_fixed) - 10} more" if len(declared_fixed) > 10 else ""
        warnings.append(f'{reader.path}: <ball> {shown}{more}: fixed="1" has no effect in a '
                        "ball2d scene, as in SCISim (which never scripts a ball): a fixed ball "
                        "moves, feels gravity and takes impulses like any other")
    table = np.array(rows, dtype=float).reshape(-1, 6)
    return Bodies(positions=table[:, 0:2].copy(), velocities=table[:, 2:4].copy(),
                  masses=table[:, 4].copy(), radii=table[:, 5].copy(),
                  fixed=np.zeros(len(rows), dtype=bool))


def _rigidbody2d_bodies(reader: _Reader, children: dict[str, list[Element]],
                        warnings: list[str]) -> Bodies:
    """``<geometry type="circle" r/>`` in file order and ``<rigid_body x theta v omega rho
    geo_idx fixed/>``; circles: m = rho pi r^2; boxes ``<geometry type="box" r="hx hy"/>``:
    m = rho 4 hx hy (half-widths must be positive)."""
    geometries: list[tuple[str, np.ndarray]] = []
    for index, geometry in enumerate(children.get("geometry", [])):
        kind = reader.text(geometry, "type", index).strip()
        if kind == "circle":
            radius = reader.number(geometry, "r", index, check="positive")
            geometries.append(("circle", np.array([radius, math.nan])))
        elif kind == "box":
            geometries.append(("box", reader.vector(geometry, "r", index, positive=True)))
        else:
            raise reader.error(geometry, "type", f"must be circle or box, got {shown(kind)}", index)
    rows = []
    halves = []
    for index, body in enumerate(children.get("rigid_body", [])):
        geo_idx = reader.integer(body, "geo_idx", index)
        if not 0 <= geo_idx < len(geometries):
            raise reader.error(body, "geo_idx", f"out of range: {geo_idx} (the scene has "
                               f"{len(geometries)} <geometry> elements)", index)
        kind, size = geometries[geo_idx]
        rho = reader.number(body, "rho", index, check="positive")
        position = reader.vector(body, "x", index)
        velocity = reader.vector(body, "v", index)
        if kind == "box":  # SCISim's BoxGeometry: m = rho 4 hx hy; radius = |r| for bounds
            mass, radius = rho * 4.0 * size[0] * size[1], float(np.hypot(*size))
            halves.append(size)
        else:
            mass, radius = rho * math.pi * size[0] ** 2, float(size[0])
            halves.append(np.array([math.nan, math.nan]))
        rows.append((
            *position, *velocity, mass, radius,
            float(reader.boolean(body, "fixed", index, default=False)),
            reader.number(body, "theta", index), reader.number(body, "omega", index),
        ))
    table = np.array(rows, dtype=float).reshape(-1, 9)
    return Bodies(positions=table[:, 0:2].copy(), velocities=table[:, 2:4].copy(),
                  masses=table[:, 4].copy(), radii=table[:, 5].copy(),
                  fixed=table[:, 6] > 0.5, theta=table[:, 7].copy(), omega=table[:, 8].copy(),
                  half_widths=(np.array(halves).reshape(-1, 2)
                               if any(not np.isnan(h[0]) for h in halves) else None))


def _integrator(reader: _Reader, children: dict[str, list[Element]]) -> tuple[str, Fraction]:
    if "integrator" not in children:
        raise InputError(reader.path, "missing: a scene needs one", element="integrator")
    element = children["integrator"][0]
    kind = reader.text(element, "type").strip()
    if kind not in INTEGRATORS:
        raise reader.error(element, "type", f"must be one of {', '.join(INTEGRATORS)}, "
                                            f"got {shown(kind)}")
    return kind, reader.fraction(element, "dt")


def _gravity(reader: _Reader, children: dict[str, list[Element]],
             dialect: str) -> np.ndarray | None:
    """The sum of every gravity element (an acceleration), or None when there is none."""
    total: np.ndarray | None = None
    if dialect == "ball2d":
        for index, element in enumerate(children.get("gravity", [])):
            value = np.array([reader.number(element, "fx", index),
                              reader.number(element, "fy", index)])
            total = value if total is None else total + value
    else:
        for index, element in enumerate(children.get("near_earth_gravity", [])):
            value = reader.vector(element, "f", index)
            total = value if total is None else total + value
    return total


def _planes(reader: _Reader, children: dict[str, list[Element]]
            ) -> tuple[np.ndarray, np.ndarray]:
    """``<static_plane x="px py" n="nx ny"/>`` with n normalized."""
    points, normals = [], []
    for index, plane in enumerate(children.get("static_plane", [])):
        points.append(reader.vector(plane, "x", index))
        normal = reader.vector(plane, "n", index)
        length = float(np.hypot(normal[0], normal[1]))
        if not length > 1e-300:
            raise reader.error(plane, "n", "must be a non-zero normal", index)
        normals.append(normal / length)
    return np.array(points, dtype=float).reshape(-1, 2), np.array(normals).reshape(-1, 2)


def _portals(reader: _Reader, children: dict[str, list[Element]], points: np.ndarray,
             normals: np.ndarray) -> tuple[list[Portal], np.ndarray, np.ndarray]:
    """``<planar_portal planeA planeB/>`` and ``<lees_edwards_portal planeA planeB v
    bounds/>`` (planar ones first, as SCISim orders them); their planes stop being walls."""
    portals: list[Portal] = []
    used: list[int] = []
    for tag in _PORTALS:
        for index, element in enumerate(children.get(tag, [])):
            pair = []
            for name in ("planeA", "planeB"):
                plane = reader.integer(element, name, index)
                if not 0 <= plane < points.shape[0]:
                    raise reader.error(element, name, f"names plane {plane}, but the scene has "
                                       f"{points.shape[0]} <static_plane>", index)
                if plane in used or plane in pair:
                    raise reader.error(element, name, f"plane {plane} is already a portal "
                                       "plane", index)
                pair.append(plane)
            v = bounds = 0.0
            if tag == "lees_edwards_portal":
                v = reader.number(element, "v", index)
                bounds = reader.number(element, "bounds", index, check="positive")
            used.extend(pair)
            a, b = pair
            portals.append(Portal(points[a].copy(), normals[a].copy(), points[b].copy(),
                                  normals[b].copy(), v, bounds))
    keep = np.setdiff1d(np.arange(points.shape[0]), used)
    return portals, points[keep].reshape(-1, 2), normals[keep].reshape(-1, 2)


def _drums(reader: _Reader, children: dict[str, list[Element]]
           ) -> tuple[np.ndarray, np.ndarray]:
    """``<static_drum x y r/>``: keeps balls inside the circle."""
    centers, radii = [], []
    for index, drum in enumerate(children.get("static_drum", [])):
        centers.append((reader.number(drum, "x", index), reader.number(drum, "y", index)))
        radii.append(reader.number(drum, "r", index, check="positive"))
    return np.array(centers, dtype=float).reshape(-1, 2), np.array(radii, dtype=float)


def _impact(reader: _Reader, children: dict[str, list[Element]], dialect: str
            ) -> tuple[ImpactOperator | None, FrictionSolver | None]:
    """The impact operator, or the friction solver; a friction solver with mu = 0 also
    declares the frictionless ``lcp`` with its CoR, which is what the simulator then runs."""
    friction = [element for tag in _FRICTION_SOLVERS for element in children.get(tag, [])]
    if "impact_operator" in children and friction:
        raise InputError(reader.path, f"a scene has an impact operator or <{friction[0].tag}>, "
                                      "not both", element="impact_operator")
    if len(friction) > 1:
        raise InputError(reader.path, "appears twice; a scene has one friction solver",
                         element=friction[1].tag)
    if friction:
        element = friction[0]
        if element.tag == "sobogus_friction_solver":
            solver = _sobogus(reader, element, dialect)
        else:
            solver = _staggered_projections(reader, element)
        if solver.frictional:
            return None, solver
        return ImpactOperator(type="lcp", restitution=solver.restitution, v_tol=0.0,
                              cache_impulses=solver.cache_impulses != "none",
                              declared_by=element.tag), solver
    if "impact_operator" in children:
        return _operator(reader, children["impact_operator"][0], restitution=None), None
    return None, None


def _sobogus(reader: _Reader, element: Element, dialect: str) -> FrictionSolver:
    """``<sobogus_friction_solver mu CoR max_iters eval_every tol cache_impulses staggering>``,
    every attribute required, as SCISim reads it; ``symplectic_euler`` (ball2d only, CoR 0)
    adds ``stabilization`` and ``penetration_threshold``; ``stabilized`` takes no cache in
    ball2d (rigidbody2d accepts one and never uses it)."""
    mu = reader.number(element, "mu", check="nonnegative")
    restitution = reader.number(element, "CoR", check="unit")
    max_iters = reader.integer(element, "max_iters", check="positive")
    eval_every = reader.integer(element, "eval_every", check="positive")
    if eval_every > max_iters:
        raise reader.error(element, "eval_every", f"must be <= max_iters ({max_iters}), got "
                                                  f"{eval_every}")
    tol = reader.number(element, "tol", check="nonnegative")
    cache = reader.choice(element, "cache_impulses", CACHE_MODES)
    allowed = STAGGERINGS if dialect == "ball2d" else ("geometric", "stabilized")
    staggering = reader.choice(element, "staggering", allowed)
    solver = FrictionSolver(kind="sobogus", mu=mu, restitution=restitution,
                            staggering=staggering, tol=tol, max_iters=max_iters,
                            eval_every=eval_every, cache_impulses=cache,
                            declared_by=element.tag)
    if staggering == "symplectic_euler":
        if restitution != 0.0:
            raise reader.error(element, "CoR", "must be 0 for the symplectic_euler staggering "
                                               f"(as SCISim requires), got "
                                               f"{shown(element.get('CoR', ''))}")
        solver.stabilization = reader.boolean(element, "stabilization")
        solver.penetration_threshold = reader.number(element, "penetration_threshold",
                                                     check="nonnegative")
    if staggering == "stabilized":
        if dialect == "ball2d" and cache != "none":
            raise reader.error(element, "cache_impulses", "must be none for the stabilized "
                                                          f"staggering (as SCISim requires), "
                                                          f"got {cache!r}")
        solver.cache_impulses = "none"  # SCISim's stabilized map always starts from zero
    return solver


def _staggered_projections(reader: _Reader, element: Element) -> FrictionSolver:
    """``<staggered_projections_friction_solver mu CoR tol max_iters staggering>`` with its
    ``<lcp_impact_solver name>`` (the normal QP's solver, mapped like ``<solver>``) and
    ``<mdp_friction_solver name>`` (the friction box QP's) children."""
    mu = reader.number(element, "mu", check="nonnegative")
    restitution = reader.number(element, "CoR", check="unit")
    tol = reader.number(element, "tol", check="nonnegative")
    max_iters = reader.integer(element, "max_iters", check="positive")
    staggering = reader.choice(element, "staggering", ("geometric", "stabilized"))
    children: dict[str, list[Element]] = {}
    for child in element:
        if not isinstance(child.tag, str):
            continue
        if child.tag not in _SP_CHILDREN:
            reader.unknown.append(f"<{element.tag}><{child.tag}>")
            continue
        children.setdefault(child.tag, []).append(child)
    for tag in sorted(_SP_CHILDREN):
        if tag not in children:
            raise InputError(reader.path, f"missing: <{element.tag}> needs a <{tag} name=...> "
                                          "child", element=tag)
        if len(children[tag]) > 1:
            raise InputError(reader.path, f"appears {len(children[tag])} times in "
                                          f"<{element.tag}>", element=tag)
    impact = _solver(reader, children["lcp_impact_solver"][0])
    friction_name = reader.text(children["mdp_friction_solver"][0], "name").strip()
    return FrictionSolver(kind="staggered_projections", mu=mu, restitution=restitution,
                          staggering=staggering, tol=tol, max_iters=max_iters,
                          impact_solver=impact, friction_solver_name=friction_name,
                          declared_by=element.tag)


def _cache_impulses(reader: _Reader, element: Element) -> bool:
    """``cache_impulses``: 0/1 (impact operators) or none/normal/normal_and_friction (friction
    solvers; without friction both of the latter cache the normal impulses)."""
    raw = element.get("cache_impulses")
    if raw is None:
        return False
    value = raw.strip()
    if value in ("0", "none"):
        return False
    if value in ("1", "normal", "normal_and_friction"):
        return True
    raise reader.error(element, "cache_impulses", "must be 0, 1, none, normal or "
                                                  f"normal_and_friction, got {shown(raw)}")


def _operator(reader: _Reader, element: Element, restitution: float | None) -> ImpactOperator:
    """``<impact_operator>`` (or a grr's ``<elastic_operator>``/``<inelastic_operator>``, whose
    restitution is fixed at 1 and 0)."""
    reader.note_unknown(element, _COMMON["impact_operator"])
    kind = reader.text(element, "type").strip()
    if kind not in OPERATORS:
        raise reader.error(element, "type",
                           f"must be one of {', '.join(OPERATORS)}, got {shown(kind)}")
    if restitution is None:
        restitution = reader.number(element, "CoR", check="unit")
    elif element.get("CoR") is not None:
        reader.number(element, "CoR", check="unit")
    operator = ImpactOperator(
        type=kind, restitution=restitution,
        v_tol=reader.number(element, "v_tol", default=1e-9, check="nonnegative"),
        cache_impulses=_cache_impulses(reader, element),
        declared_by=element.tag,
    )
    children: dict[str, list[Element]] = {}
    for child in element:
        if not isinstance(child.tag, str):
            continue
        if child.tag not in _OPERATOR_CHILDREN:
            reader.unknown.append(f"<{element.tag}><{child.tag}>")
            continue
        children.setdefault(child.tag, []).append(child)
    for tag, items in children.items():
        if len(items) > 1:
            raise InputError(reader.path, f"appears {len(items)} times in <{element.tag}>",
                             element=tag)
    if kind in ("lcp", "gr"):
        if "solver" not in children:
            raise InputError(reader.path, f"missing: <{element.tag} type={kind!r}> needs a "
                                          "<solver name=...> child", element="solver")
        operator.solver = _solver(reader, children["solver"][0])
    if kind == "grr":
        for tag, value in (("elastic_operator", 1.0), ("inelastic_operator", 0.0)):
            if tag not in children:
                raise InputError(reader.path, f"missing: <{element.tag} type='grr'> needs "
                                              f"<{tag}>", element=tag)
            if children[tag][0].get("type", "").strip() == "grr":  # before reading it: a
                # chain of nested grr operators would otherwise recurse as deep as it goes
                raise reader.error(children[tag][0], "type", "a grr cannot nest another grr")
            sub = _operator(reader, children[tag][0], restitution=value)
            setattr(operator, tag.removesuffix("_operator"), sub)
    return operator


def _solver(reader: _Reader, element: Element) -> SolverChoice:
    name = reader.text(element, "name").strip()
    mapped = qpbench_name(name)
    if mapped is None:
        raise reader.error(element, "name", f"unknown SCISim solver {shown(name)} (known: "
                                            f"{', '.join(SCISIM_TO_QPBENCH)})")
    options = {key: value for key, value in element.attrib.items() if key != "name"}
    return SolverChoice(scisim_name=name, qpbench_name=mapped, options=options)

