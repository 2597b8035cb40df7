"""benchmarks/false_plaques.py: predicted plaques sorted by what lies under them."""

from __future__ import annotations

import numpy as np
import pytest

from _benchmarks import benchmark_module


@pytest.fixture(scope="module")
def false_plaques():
    yield from benchmark_module("false_plaques")


def test_predicted_plaques_are_sorted_by_the_plaques_and_scratches_under_them(false_plaques):
    true = np.zeros((20, 30), np.uint16)
    true[2:6, 2:6] = 1
    scraped = np.zeros((20, 30), bool)
    scraped[10:12, :] = True  # a scratch across the image, two rows wide
    predicted = np.zeros((20, 30), np.int32)
    predicted[2:6, 3:7] = 1  # 12 of 16 pixels on the rendered plaque: found
    predicted[9:13, 10:14] = 2  # half on the scratch: false, on a scratch
    predicted[9:13, 20:24] = 5  # a third on the scratch, more than 0.3
    predicted[15:19, 20:24] = 7  # on nothing: false elsewhere
    tally = false_plaques.sort_predicted(predicted, true, scraped)
    assert (tally.found, tally.false_on_scratches, tally.false_elsewhere, tally.false) == (1, 2, 1, 3)
    strict = false_plaques.sort_predicted(predicted, true, scraped, overlap=0.6)
    assert (strict.found, strict.false_on_scratches, strict.false_elsewhere) == (1, 0, 3)
    total = false_plaques.PlaqueTally()
    total.add(tally)
    total.add(strict)
    assert (total.found, total.false_on_scratches, total.false_elsewhere) == (2, 2, 4)
    empty = false_plaques.sort_predicted(np.zeros((4, 4), np.int32), true[:4, :4], scraped[:4, :4])
    assert empty.false == empty.found == 0


def test_plaques_are_placed_by_where_they_lie_in_their_well(false_plaques):
    yy, xx = np.mgrid[:100, :220]
    wells = np.zeros((100, 220), np.uint8)
    wells[(yy - 50) ** 2 + (xx - 50) ** 2 <= 40**2] = 1  # radius 40 around (50, 50)
    wells[(yy - 50) ** 2 + (xx - 160) ** 2 <= 40**2] = 2  # the same around (50, 160), in the last row
    plaques = np.zeros_like(wells, np.uint16)
    spots = {1: (50, 50), 2: (13, 52), 3: (87, 48), 4: (52, 87), 5: (87, 160), 6: (50, 197), 7: (50, 140)}
    for plaque, (y, x) in spots.items():
        plaques[y - 2:y + 3, x - 2:x + 3] = plaque
    plaques[0:3, 100:103] = 8  # outside every well: left out
    plaques[5:12, 48:53] = 9  # astride well 1's top edge (row 10), most of it outside: left out, as the counts do
    places = false_plaques.place_in_well(wells, plaques, last_row={2})
    assert places == ["inside", "rim, top", "rim, bottom, other rows", "rim, side", "rim, bottom, last row",
                      "rim, side", "inside"]
    assert set(places) <= set(false_plaques.PLACES)
    assert false_plaques.place_in_well(wells, np.zeros_like(plaques)) == []
