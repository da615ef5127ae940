"""The drag mode of the face panel (repro.ui.drag_panel.DragPanel): its numbers are DirectManipulator's."""

import numpy as np
import pytest

from repro.blendshapes import load_model
from repro.blendshapes.manipulation import DirectManipulator
from repro.errors import ModelError
from repro.ui.drag_panel import DragPanel
from repro.ui.face_panel import parse_numbers


@pytest.fixture(scope="module")
def face():
    return load_model("procedural")


def test_drag_shows_the_manipulator_solution(face):
    p = DragPanel(face, view="none", region="under_left_eye")
    p.set_sliders(JawOpen=0.3)
    w0 = p.weights
    p.set_drag(True, region="mouth_corners")
    np.testing.assert_allclose(p.weights, w0, atol=1e-12)  # no offset yet: nothing moves
    p.set_target_offset(dx=0.05, dy=0.1)
    dm = DirectManipulator(face)
    corners = face.regions["mouth_corners"]
    targets = dm.positions(w0, corners) + np.array([0.05, 0.1, 0.0])
    from repro.blendshapes import select_vertices

    pin = select_vertices(face.regions["under_left_eye"], n_vertices=face.n_vertices)
    want = dm.solve(w0, corners, targets, pin, lo=0.0, hi=1.0, info=True)
    np.testing.assert_allclose(p.weights, want.w, atol=1e-12)
    np.testing.assert_allclose(p.drag_targets, targets)
    assert p.drag_result.n_sliders_moved == want.n_sliders_moved
    assert "dragged error:" in p.drag_text and parse_numbers(p.numbers_text)["attenuation"] == "drag"
    # unpinned and unbounded: a different solve
    p.pin_box.value = False
    p.bounded_box.value = False
    np.testing.assert_allclose(p.weights, dm.solve(w0, corners, targets), atol=1e-12)
    # drag off: the sliders act again
    p.set_drag(False)
    np.testing.assert_allclose(p.weights, w0)
    assert p.drag_text == "" and p.drag_result is None


def test_drag_region_change_restarts_from_the_displayed_pose(face):
    p = DragPanel(face, view="none", region="under_left_eye")
    p.set_drag(True, region="mouth_corners")
    p.set_target_offset(dy=0.1)
    w_after_first = p.weights
    p.drag_region.value = "brow_middle"
    assert all(s.value == 0.0 for s in p.offset_sliders.values())
    np.testing.assert_allclose(p.weights, w_after_first, atol=1e-12)


def test_drag_errors_are_shown_not_raised(face):
    p = DragPanel(face, view="none", region="mouth_corners")
    p.set_drag(True, region="mouth_corners")  # dragged = pinned
    assert p.error is not None and "both dragged and pinned" in p.error
    assert p.numbers_text.startswith("error:")
    p.pin_box.value = False
    assert p.error is None
    with pytest.raises(ModelError, match="unknown drag region"):
        p.set_drag(True, region="nowhere")
    with pytest.raises(ModelError, match="drag_range"):
        DragPanel(face, view="none", drag_range=-1.0)


def test_added_regions_can_be_dragged_and_the_view_renders(face):
    p = DragPanel(face, view="matplotlib")
    p.add_region("one vertex", [100], select=False)
    assert "one vertex" in p.drag_region.options
    p.set_drag(True, region="one vertex")
    p.set_target_offset(dz=0.05)
    assert p.image_png()[:4] == b"\x89PNG"
    assert repr(p).startswith("DragPanel(")
    p.close()
