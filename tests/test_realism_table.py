"""The realism table's paired differences between presets over sets of scenes (benchmarks/realism_table.py)."""

from __future__ import annotations

import numpy as np
import pytest

from _benchmarks import benchmark_module


@pytest.fixture(scope="module")
def table():
    yield from benchmark_module("realism_table")


def rows_of(table, values: list[float]) -> list[dict[str, float]]:
    """One row per scene set, every column at 0 but ``fd_wells``."""
    return [{column: (value if column == "fd_wells" else 0.0) for column in table.COLUMNS} for value in values]


def test_paired_differences_are_taken_set_by_set(table):
    # the sets move the presets together by tens; their difference stays 5 or 7
    rows = {"high": rows_of(table, [274.0, 241.0, 260.0]), "look": rows_of(table, [279.0, 248.0, 265.0]),
            "same": rows_of(table, [274.0, 241.0, 260.0])}
    differences = table.paired_differences(rows)
    assert list(differences) == ["look", "same"]  # every preset but the first
    fd = table.COLUMNS.index("fd_wells")
    mean, sd = differences["look"]
    assert mean[fd] == pytest.approx(17.0 / 3.0) and sd[fd] == pytest.approx(np.std([5.0, 7.0, 5.0], ddof=1))
    assert np.all(mean[np.arange(len(table.COLUMNS)) != fd] == 0.0)
    assert np.all(differences["same"][0] == 0.0) and np.all(differences["same"][1] == 0.0)


def test_one_set_has_no_spread_and_unequal_sets_are_an_error(table):
    mean, sd = table.paired_differences({"high": rows_of(table, [274.0]), "look": rows_of(table, [280.0])})["look"]
    assert mean[table.COLUMNS.index("fd_wells")] == 6.0 and np.isnan(sd).all()
    with pytest.raises(ValueError):
        table.paired_differences({"high": rows_of(table, [274.0, 241.0]), "look": rows_of(table, [280.0])})
