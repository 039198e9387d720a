"""Measuring a category's variation: known boxes give known measurements; summaries and tables."""

from __future__ import annotations

import numpy as np
import pytest

from ancsh.data.conventions import convention
from ancsh.data.measure import measure_instance, procedural_summary, summarize
from ancsh.studies.catalog_reports import ranges_table
from ancsh.data.procedural import _door
from ancsh.data.procedural import _mesh as m
from ancsh.data.procedural import make_object
from ancsh.model.articulated import ArticulatedModel, Part

WIDTH, HEIGHT, DEPTH = 0.6, 0.4, 0.5  # body (metres)
DOOR_W, DOOR_H, DOOR_T = 0.45, 0.3, 0.03  # door slab
Y0 = 0.05  # door's lower edge
REL = 1e-9


def _boxed_door(hinge: str, inset: bool = False, category: str = "microwave") -> ArticulatedModel:
    """A box body with a plain slab door (no handle) on ``hinge``, the door centred in x."""
    x0 = -DOOR_W / 2
    if hinge == "top":  # a lid on the top face, from the back edge forwards
        door = _door.DoorFrame(x0, x0 + DOOR_W, -DEPTH / 2 + 0.05, -DEPTH / 2 + 0.05 + DOOR_H, HEIGHT, DOOR_T, hinge)
        body = [m.box_between([-WIDTH / 2, 0.0, -DEPTH / 2], [WIDTH / 2, HEIGHT, DEPTH / 2])]
    else:
        door = _door.DoorFrame(x0, x0 + DOOR_W, Y0, Y0 + DOOR_H, DEPTH / 2, DOOR_T, hinge, inset)
        opening = (door.x0, door.x1, door.a0, door.a1)
        body = _door.cavity_body(-WIDTH / 2, WIDTH / 2, 0.0, HEIGHT, -DEPTH / 2, DEPTH / 2, opening, DEPTH / 2)
    slab = door.box([0.0, 0.0, 0.0], [DOOR_W, DOOR_H, DOOR_T])
    return ArticulatedModel((Part("base", m.concat(body)), Part("door", slab)), (door.joint("door_hinge", np.pi / 2),),
                            name=f"box_{hinge}", category=category)


@pytest.mark.parametrize("hinge", ["left", "right", "bottom"])
def test_a_front_door_is_measured_with_its_hinge_size_and_thickness(hinge):
    mm = measure_instance(_boxed_door(hinge), convention("microwave"))
    assert mm["door_on"] == "front" and mm["hinge"] == hinge
    assert mm["door_width_frac"] == pytest.approx(DOOR_W / WIDTH, rel=REL)
    assert mm["door_length_frac"] == pytest.approx(DOOR_H / HEIGHT, rel=REL)
    assert mm["door_centre_height_frac"] == pytest.approx((Y0 + DOOR_H / 2) / HEIGHT, rel=REL)
    assert mm["door_thickness_frac"] == pytest.approx(DOOR_T / WIDTH, rel=REL)
    assert mm["door_recess_frac"] == 0.0
    assert mm["height_over_width"] == pytest.approx(HEIGHT / WIDTH, rel=REL)
    assert mm["depth_over_width"] == pytest.approx(DEPTH / WIDTH, rel=REL)
    assert mm["depth"] == pytest.approx(DEPTH + DOOR_T, rel=REL)


def test_an_inset_door_is_recessed_by_its_thickness():
    mm = measure_instance(_boxed_door("left", inset=True), convention("safe"))
    assert mm["hinge"] == "left"
    assert mm["door_recess_frac"] == pytest.approx(DOOR_T / DEPTH, rel=REL)


def test_a_top_lid_hinges_at_its_back():
    mm = measure_instance(_boxed_door("top", category="washing_machine"), convention("washing_machine"))
    assert mm["door_on"] == "top" and mm["hinge"] == "back"
    assert mm["door_length_frac"] == pytest.approx(DOOR_H / DEPTH, rel=REL)
    assert "door_recess_frac" not in mm


def test_drawers_laptops_and_eyeglasses_get_their_measurements():
    drawer = measure_instance(make_object("drawer", 0), convention("drawer"))
    assert drawer["drawers"] == len(convention("drawer").joints)
    assert 0 < drawer["drawers_bottom_frac"] < drawer["drawers_top_frac"] <= 1
    laptop = measure_instance(make_object("laptop", 0), convention("laptop"))
    assert laptop["base_thickness_frac"] == pytest.approx(laptop["height_over_width"])
    assert laptop["display_thickness_frac"] > 0 and 0.5 < laptop["display_length_frac"] <= 1.0  # closed: lid over the base
    glasses = measure_instance(make_object("eyeglasses", 0), convention("eyeglasses"))
    assert glasses["temple_length_ratio"] > 0 and glasses["temple_drop_ratio"] > 0


def test_summaries_give_ranges_and_shares_and_the_table_puts_them_side_by_side():
    values = [{"w": 1.0, "side": "left"}, {"w": 3.0, "side": "right"}, {"w": 2.0, "side": "left"}, {"w": 5.0}]
    s = summarize(values)
    assert s["w"] == {"n": 4, "min": 1.0, "median": 2.5, "max": 5.0}
    assert s["side"] == {"n": 3, "shares": {"left": 2 / 3, "right": 1 / 3}}
    table = ranges_table({"real": s, "procedural": summarize([{"w": 2.0}])})
    header, rule, *rows = table.strip().splitlines()
    assert header == "| measurement | real | procedural |" and rule.count("|") == 4
    assert rows == ["| w | 1 - 5 (2.5) | 2 - 2 (2) |", "| side | left 67 %, right 33 % | - |"]
    with pytest.raises(ValueError, match="measurements"):
        summarize([])
    with pytest.raises(ValueError, match="summaries"):
        ranges_table({})


def test_procedural_summary_covers_the_first_instances_and_checks_its_arguments():
    s = procedural_summary("microwave", 3)
    assert s["hinge"]["n"] == 3 and s["diagonal"]["n"] == 3
    with pytest.raises(ValueError, match="n: expected"):
        procedural_summary("microwave", 0)
    with pytest.raises(ValueError, match="model"):
        measure_instance("not a model", convention("oven"))
    with pytest.raises(ValueError, match="conv"):
        measure_instance(make_object("oven", 0), "oven")
