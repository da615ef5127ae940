"""Vertices picked on the face's 3D view (repro.ui.face_picking; issue 26, item 10), driven from code.

The page's side (a click or a brush on the canvas writing a message) is checked in
tests/browser/test_screens.py; here: the messages, and that the picked vertices are Eq. 3's S as a preset's are.
"""

from __future__ import annotations

import numpy as np
import pytest

from repro.blendshapes import load_model, select_vertices
from repro.errors import SelectionError
from repro.ui.face_panel import BlendshapePanel
from repro.ui.face_picking import PICKED, VertexPicks, parse_pick
from repro.ui.webview import unpack


@pytest.fixture(scope="module")
def face():
    return load_model("procedural")


def test_pick_messages_are_read_or_refused():
    p = parse_pick("1733390000123 add 7 3 7 12", 100)
    assert p.seq == 1733390000123 and p.action == "add" and p.vertices.tolist() == [3, 7, 12]
    c = parse_pick(" 5 clear ", 100)
    assert c.seq == 5 and c.action == "clear" and c.vertices.size == 0
    for bad in ["", "5", "5 add", "5 add -1", "5 add 1.5", "x add 1", "5 remove 1", "5 clear 1", "5 add 1,2", None,
                "5 add " + " ".join(["1"] * 600_000)]:
        with pytest.raises(SelectionError):
            parse_pick(bad, 100)
    with pytest.raises(SelectionError, match="not on the face"):
        parse_pick("5 add 100", 100)
    picks = VertexPicks(10)
    assert picks.take("3 add 1") is not None and picks.take("2 add 2") is None and picks.take("3 add 2") is None
    with pytest.raises(SelectionError):
        picks.add([10])


def test_picked_vertices_are_the_selection_of_eq3_as_a_preset_is(face):
    panel = BlendshapePanel(face, view="3d", region="under_left_eye", attenuation=True)
    assert PICKED in panel.region.options and panel.picked_vertices.size == 0
    preset = panel.selected_vertices
    # a click while a preset is shown adds to what is shown (the cyan vertices)
    panel._view.picks.value = "10 add 40"
    assert panel.region.value == PICKED
    want = np.union1d(preset, [40])
    np.testing.assert_array_equal(panel.picked_vertices, want)
    np.testing.assert_array_equal(panel.selected_vertices, want)
    # a brush stroke adds more; the selection is select_vertices of the picks, the same S a region would give
    panel._view.picks.value = "11 add 41 42 43 40"
    want = np.union1d(want, [41, 42, 43])
    np.testing.assert_array_equal(panel.selection, select_vertices(want, "xyz", face.n_vertices))
    panel.set_sliders(Wince=0.7, SneerLeft=0.7)
    same = BlendshapePanel(face, view="none", attenuation=True)
    same.add_region("tagged", want)
    same.set_sliders(Wince=0.7, SneerLeft=0.7)
    assert panel.numbers == same.numbers and np.array_equal(panel.weights, same.weights)
    # the frame drawn shows them as the selection, and tells the page which message it answers
    head, arrays = unpack(panel._view.frame.value)
    assert head["picks"] == 11 and arrays["selected"].tolist() == want.tolist()
    # the axes boxes apply to picks as to presets
    panel.set_selection(axes="y")
    np.testing.assert_array_equal(panel.selection, select_vertices(want, "y", face.n_vertices))
    # an older message (a page reloaded mid-stroke) is not applied again
    panel._view.picks.value = "9 add 500"
    assert 500 not in panel.picked_vertices
    # clear: nothing selected, said as a state (not a red error), and nothing raised
    panel._view.picks.value = "12 clear"
    assert panel.picked_vertices.size == 0 and panel.selection is None
    assert "no vertex picked" in panel.status_html.value and "error" not in panel.status_html.value
    assert unpack(panel._view.frame.value)[0]["picks"] == 12
    # a preset again: the picks stay where they were, to return to
    panel._view.picks.value = "13 add 5"
    panel.set_selection(region="mouth")
    assert panel.picked_vertices.tolist() == [5] and panel.selected_vertices.size > 1
    # a bad message is shown in the panel, not raised
    panel._view.picks.value = "14 add 99999999"
    assert "not on the face" in panel.status_html.value
    panel.close()
    same.close()


def test_picking_from_code_on_any_view(face):
    panel = BlendshapePanel(face, view="none", region="brow_middle")
    assert PICKED not in panel.region.options  # offered once something is picked (no view to click on)
    panel.pick_vertices([100, 101])
    assert panel.region.value == PICKED and panel.picked_vertices.tolist() == sorted(
        {100, 101, *face.regions["brow_middle"]})
    panel.clear_picks()
    assert panel.selection is None and panel.numbers_text.startswith("error: no vertex picked")
    panel.close()
