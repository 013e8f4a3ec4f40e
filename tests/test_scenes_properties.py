"""Mutated shared scenes: dropped, corrupted or duplicated attributes and elements.

Whatever the mutation, reading and briefly simulating the scene either works or
raises qpbench's own one-line error (InputError / UnsupportedError); nothing else.
"""

from __future__ import annotations

import copy
import xml.etree.ElementTree as ET
from pathlib import Path

import defusedxml.ElementTree as SafeET
import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from qpbench.errors import QpbenchError
from qpbench.inner_solvers import choose_by_name
from qpbench.scenes import parse_scene
from qpbench.simulation.stepper import Simulator

SCENES = Path(__file__).resolve().parents[1] / "problems" / "scenes"
SMALL_SCENES = sorted(p for p in SCENES.rglob("*.xml") if p.stat().st_size < 20_000)
CORRUPT_VALUES = ["", "abc", "nan", "inf", "-inf", "-1", "0", "1e400", "1/0", "0 0", "2",
                  "-0.5", "1 2 3", "   ", "0x10", "1e-300", "box", "gr"]
OPERATIONS = ("drop_attribute", "corrupt_attribute", "duplicate_attribute", "drop_element",
              "duplicate_element")


def mutate(text: str, data: st.DataObject) -> str:
    """One random mutation of the scene text (see the module docstring)."""
    root = SafeET.fromstring(text.encode())
    elements = [element for element in root.iter() if isinstance(element.tag, str)]
    parents = {child: parent for parent in elements for child in parent}
    operation = data.draw(st.sampled_from(OPERATIONS), label="operation")
    if operation.endswith("_element"):
        children = [element for element in elements if element in parents]
        element = data.draw(st.sampled_from(children), label="element")
        parent = parents[element]
        if operation == "drop_element":
            parent.remove(element)
        else:
            parent.insert(list(parent).index(element) + 1, copy.deepcopy(element))
        return ET.tostring(root, encoding="unicode")
    with_attributes = [element for element in elements if element.attrib]
    element = data.draw(st.sampled_from(with_attributes), label="element")
    name = data.draw(st.sampled_from(sorted(element.attrib)), label="attribute")
    if operation == "drop_attribute":
        del element.attrib[name]
    elif operation == "corrupt_attribute":
        element.set(name, data.draw(st.sampled_from(CORRUPT_VALUES), label="value"))
    else:  # a duplicated attribute makes the XML malformed
        marker = "qpbench-duplicate-marker"
        element.set(marker, "")
        serialized = ET.tostring(root, encoding="unicode")
        return serialized.replace(f'{marker}=""', f'{name}="1" {name}="2"', 1)
    return ET.tostring(root, encoding="unicode")


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(path=st.sampled_from(SMALL_SCENES), data=st.data())
def test_mutated_scenes_give_success_or_one_qpbench_line(path: Path, data: st.DataObject) -> None:
    text = mutate(path.read_text(), data)
    try:
        scene = parse_scene(text, path.name)
        result = Simulator(scene, choose_by_name("clarabel/dual")).run(max_steps=3)
    except QpbenchError as error:
        message = str(error)
        assert message and "\n" not in message
        assert "Traceback" not in message
        return
    assert result.steps <= 3
    assert np.all(np.isfinite(result.x_final))


@settings(max_examples=15, deadline=None)
@given(path=st.sampled_from(SMALL_SCENES), data=st.data())
def test_duplicated_attributes_are_malformed_xml(path: Path, data: st.DataObject) -> None:
    root = SafeET.fromstring(path.read_bytes())
    element = data.draw(st.sampled_from([e for e in root.iter() if e.attrib]))
    name = data.draw(st.sampled_from(sorted(element.attrib)))
    element.set("qpbench-marker", "")
    text = ET.tostring(root, encoding="unicode").replace('qpbench-marker=""',
                                                         f'{name}="0"', 1)
    try:
        parse_scene(text, path.name)
    except QpbenchError as error:
        assert "malformed XML" in str(error) and "\n" not in str(error)
    else:
        raise AssertionError("a duplicated attribute was accepted")
