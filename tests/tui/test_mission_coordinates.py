"""The TUI's mission screen shows coordinates by the rule `mission` shows them by (output.tables.coord_text)."""

from __future__ import annotations


def test_the_mission_screen_shows_a_float32_coordinate_as_its_shortest_text() -> None:
    """MISSION_ITEM carries x/y as float32 degrees: 47.397743 is str(numpy.float32(47.397743)) (the
    shortest text that reads back as that float32), where `.7f` of the widened value printed 47.3977432; the
    screen and `mission` share output.tables.coord_text. MISSION_ITEM_INT's degE7 keep their 7 decimals."""
    import struct

    import numpy as np

    from mavscope.output.tables import coord_text

    widened = struct.unpack("<f", struct.pack("<f", 47.397743))[0]
    assert f"{widened:.7f}" == "47.3977432"
    assert coord_text(widened, "°", True) == str(np.float32(47.397743)) + "°" == "47.397743°"
    assert coord_text(473977432 / 1e7, "°", False) == "47.3977432°"
