"""The contact sheet's scoring of a judge's answers (benchmarks/well_contact_sheet.py)."""

from __future__ import annotations

import pytest

from _benchmarks import benchmark_module


@pytest.fixture(scope="module")
def sheet():
    yield from benchmark_module("well_contact_sheet")


def test_score_counts_renders_found_and_photos_kept(sheet, tmp_path):
    kinds = ["real", "synthetic", "synthetic", "real", "synthetic", "real"]
    key = tmp_path / "sheet.png.key.txt"
    key.write_text("".join(f"row {i // 3}, column {i % 3}: {k}\n" for i, k in enumerate(kinds)))
    answers = tmp_path / "answers.txt"
    said = ["real", "synthetic", "real", "real", "synthetic", "synthetic"]  # one render missed, one photo doubted
    answers.write_text("a judge's notes first\n" + "".join(
        f"row {i // 3}, column {i % 3}: {k}\n" for i, k in enumerate(said)))
    assert sheet.score(key, answers) == "4/6 right: 2/3 renders found, 2/3 photos called real (chance: half)"


def test_score_refuses_answers_that_miss_tiles(sheet, tmp_path):
    key = tmp_path / "sheet.png.key.txt"
    key.write_text("row 0, column 0: real\nrow 0, column 1: synthetic\n")
    answers = tmp_path / "answers.txt"
    answers.write_text("row 0, column 0: real\n")
    with pytest.raises(SystemExit, match="1 answers for the 2 tiles"):
        sheet.score(key, answers)
    with pytest.raises(SystemExit, match="other.png.key.txt: no such file"):
        sheet.score(tmp_path / "other.png.key.txt", answers)
