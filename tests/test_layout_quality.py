"""Segmentation scored on simulated scans of any layout, and where its errors lie: object by object."""

import numpy as np

from pimm_agents.measurement.layout_quality import _count_by_object, object_errors
from pimm_env.world.model import Element
from pimm_env.world.semantics import SemanticClass
from pimm_env.world.shapes import Box


def element(name: str, semantic: SemanticClass) -> Element:
    return Element(name, semantic, Box(np.zeros(3), np.ones(3)), True)


def test_objects_are_listed_by_how_many_of_their_returns_got_another_class():
    elements = [element("wall", SemanticClass.WALL), element("window", SemanticClass.CLUTTER)]
    counts: dict[int, np.ndarray] = {}
    # one scan: 4 wall returns (1 called clutter), 3 window returns (2 called wall), 1 return on a walker
    hit = np.array([0, 0, 0, 0, 1, 1, 1, -1])
    predicted = np.array([0, 0, 0, 3, 0, 0, 3, 3])
    _count_by_object(counts, hit, predicted)
    _count_by_object(counts, hit, predicted)  # a second scan adds up
    rows = object_errors(elements, counts)
    assert [row["name"] for row in rows] == ["window", "wall"]
    assert rows[0] == {
        "name": "window",
        "class": "clutter",
        "returns": 6,
        "wrong": 4,
        "labelled": {"wall": 4, "ceiling": 0, "floor": 0, "clutter": 2},
    }
    assert rows[1]["wrong"] == 2 and rows[1]["returns"] == 8
    assert object_errors(elements, counts, top=1) == rows[:1]


def test_a_worlds_objects_account_for_every_return_scored(room_file):
    from pimm_agents.measurement.layout_quality import measure_layouts
    from pimm_agents.perception.files import SHIPPED_CLOUD_WEIGHTS

    report = measure_layouts(str(room_file), SHIPPED_CLOUD_WEIGHTS, 2, 1, layouts=("thesis",), by_object=True)
    scores = report["thesis@0.5m"]
    names = {row["name"] for row in scores["objects"]}
    assert names <= {"floor", "ceiling", "south", "north", "west", "east", "post"} and "floor" in names
    assert sum(row["returns"] for row in scores["objects"]) == scores["returns"]
