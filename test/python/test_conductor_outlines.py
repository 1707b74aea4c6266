"""The room outline the conductor measures against, kept per SLAM map."""
from sparse_nav.conductor.outlines import OutlinesByMap

SQUARE = ((0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0))
WIDER = ((0.0, 0.0), (6.0, 0.0), (6.0, 4.0), (0.0, 4.0))


def test_a_map_without_an_answer_has_no_outline():
    assert OutlinesByMap().get(0) == ()


def test_an_outline_comes_back_with_its_map():
    outlines = OutlinesByMap()
    assert outlines.answered(0, SQUARE) == SQUARE
    assert outlines.get(1) == ()  # a map begun since
    assert outlines.get(0) == SQUARE  # merged back into map 0, or relocalised in it


def test_a_newer_answer_replaces_the_maps_outline():
    outlines = OutlinesByMap()
    outlines.answered(0, SQUARE)
    outlines.answered(1, WIDER)
    assert outlines.answered(0, WIDER) == WIDER
    assert outlines.get(0) == WIDER


def test_an_answer_without_a_room_keeps_the_last_outline():
    outlines = OutlinesByMap()
    outlines.answered(3, SQUARE)
    assert outlines.answered(3, ()) == SQUARE
    assert outlines.answered(3, SQUARE[:2]) == SQUARE  # two points bound no room
    assert outlines.answered(4, ()) == ()


def test_outlines_are_stored_as_float_pairs():
    outlines = OutlinesByMap()
    outlines.answered(0, [[0, 0], [4, 0], [4, 4]])
    assert outlines.get(0) == ((0.0, 0.0), (4.0, 0.0), (4.0, 4.0))
