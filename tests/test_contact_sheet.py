"""The contact sheet's scoring of a judge's answers (benchmarks/well_contact_sheet.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
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


def test_answers_that_miss_tiles_and_keys_without_classes_are_refused(sheet, tmp_path):
    key = tmp_path / "sheet.png.key.txt"
    key.write_text("row 0, column 0: real\nrow 0, column 1: synthetic\n")
    answers = tmp_path / "answers.txt"
    answers.write_text("row 0, column 0: real\n")
    with pytest.raises(SystemExit, match="1 answers for the 2 tiles"):
        sheet.score(key, answers)
    with pytest.raises(SystemExit, match="other.png.key.txt: no such file"):
        sheet.score(tmp_path / "other.png.key.txt", answers)
    answers.write_text("row 0, column 0: real\nrow 0, column 1: real\n")
    with pytest.raises(SystemExit, match="without the tiles' classes"):  # a key written before they were
        sheet.breakdown([(key, answers)])


def test_count_classes_and_tile_classes(sheet):
    assert [sheet.count_class(n) for n in (None, 0, 1, 10, 11)] == [
        "uncountable", "0 plaques", "1-10 plaques", "1-10 plaques", "over 10 plaques"]
    assert sheet.photo_class("PR8_plate4.jpg", 12) == "photo PR8, over 10 plaques"
    assert sheet.photo_class("IBV_plate1.jpg", None) == "photo IBV, uncountable"


def test_render_class_names_the_plate_and_the_wells_plaques(sheet):
    from platesynth.scene import load_config, sample_scene

    scene = sample_scene(load_config("high"), 3)
    for well in scene.wells:
        name = sheet.render_class(scene, well)
        plate = "pale" if scene.stain.saturation < sheet.PALE_SATURATION else "saturated"
        plaques = sum(p.well == well.id for p in scene.plaques)
        expected = "empty" if well.emptied else "uncountable" if not well.countable else sheet.count_class(plaques)
        assert name == f"render {plate} plate, {expected}"
    assert any(well.emptied for well in scene.wells) and any(well.countable for well in scene.wells)


def test_breakdown_counts_calls_right_per_class_over_sheets(sheet, tmp_path):
    classes = ["photo PR8, 0 plaques", "render saturated plate, 0 plaques", "photo PR8, 0 plaques",
               "render pale plate, uncountable"]
    kinds = ["real", "synthetic", "real", "synthetic"]
    plates = ["PR8_plate4.jpg", "scene 10002", "PR8_plate9.jpg", "scene 10002"]
    pairs = []
    for judge, said in enumerate((["real", "synthetic", "synthetic", "real"],
                                  ["real", "real", "real", "synthetic"])):
        key = tmp_path / f"s{judge}.png.key.txt"
        key.write_text("".join(f"row 0, column {i}: {k} | {c} | {plate} A{i} | centre RGB 80 0 218\n"
                               for i, (k, c, plate) in enumerate(zip(kinds, classes, plates))))
        answers = tmp_path / f"a{judge}.txt"
        answers.write_text("".join(f"row 0, column {i}: {k}\n" for i, k in enumerate(said)))
        pairs.append((key, answers))
    table = sheet.breakdown(pairs).splitlines()
    assert table[0].split() == ["class", "calls", "right"]
    assert [" ".join(line.split()) for line in table[1:]] == [
        "photo PR8, 0 plaques 4 3 (75%)", "render pale plate, uncountable 2 1 (50%)",
        "render saturated plate, 0 plaques 2 1 (50%)"]
    by_plate = sheet.breakdown(pairs, by="plate").splitlines()
    assert by_plate[0].split() == ["plate", "calls", "right"]
    assert [" ".join(line.split()) for line in by_plate[1:]] == [
        "PR8_plate4.jpg 2 2 (100%)", "PR8_plate9.jpg 2 1 (50%)", "scene 10002 4 2 (50%)"]


def test_a_key_line_gives_the_median_colour_of_the_tiles_middle(sheet):
    tile = np.zeros((10, 10, 3), np.uint8)
    tile[...] = (200, 200, 200)  # the border, outside the middle 6x6
    tile[2:8, 2:8] = (80, 0, 218)
    tile[2, 2] = (255, 255, 255)  # one odd pixel does not move the median
    assert sheet.centre_colour(tile) == "centre RGB 80 0 218"


def test_a_sheet_of_chosen_classes_holds_only_those_tiles(sheet, tmp_path):
    """``--photos`` and ``--renders`` keep the wells whose class matches; each key line names a matching class."""
    from conftest import shared_path

    shared_path("data", "plaque12", "counts.csv")
    out = tmp_path / "sheet.png"
    sheet.main(["--out", str(out), "--split", "check", "--wells", "3", "--tile", "64", "--seed", "2",
                "--photos", "PR8, 0 plaques", "--renders", "saturated plate, 0 plaques"])
    lines = Path(f"{out}.key.txt").read_text().splitlines()
    assert len(lines) == 6
    assert sorted(line.split(" | ")[1] for line in lines) == (
        ["photo PR8, 0 plaques"] * 3 + ["render saturated plate, 0 plaques"] * 3)
    with pytest.raises(SystemExit, match="only 0 photo wells of the check split match"):
        sheet.main(["--out", str(tmp_path / "none.png"), "--split", "check", "--photos", "IBV"])


def test_interior_keeps_the_middle_disc_and_whitens_the_rest(sheet):
    tile = np.full((100, 100, 3), 40, np.uint8)
    inside = sheet.interior_only(tile)
    assert (inside[50, 50] == 40).all() and (inside[50, 4] == 40).all()  # 45.5 px from the centre: inside 47
    assert (inside[50, 1] == 255).all() and (inside[0, 0] == 255).all()  # 48.5 px, the corner: outside
    assert (tile == 40).all()  # the tile itself is untouched


def test_breakdown_by_rim_tear_splits_the_renders_by_their_wells_tears(sheet, tmp_path):
    config = tmp_path / "torn.yaml"
    config.write_text("artifacts:\n  rim_tears: 0.3\n  rim_tear_tilt_deg: [72.0, 86.0]\n")
    torn = sheet.rim_torn_wells(5, config=config)
    scene_labels = ["A1", "A2", "A3", "A4", "B1", "B2", "B3", "B4", "C1", "C2", "C3", "C4"]
    with_tear = sorted(torn)[0]
    without = next(label for label in scene_labels if label not in torn)
    key = tmp_path / "s.png.key.txt"
    key.write_text(f"row 0, column 0: synthetic | render saturated plate, 0 plaques | scene 5 {with_tear} | centre RGB 1 2 3\n"
                   f"row 0, column 1: synthetic | render saturated plate, 0 plaques | scene 5 {without} | centre RGB 1 2 3\n"
                   "row 0, column 2: real | photo PR8, 0 plaques | PR8_plate4.jpg B1 | centre RGB 1 2 3\n")
    answers = tmp_path / "a.txt"
    answers.write_text("row 0, column 0: real\nrow 0, column 1: synthetic\nrow 0, column 2: real\n")
    table = [" ".join(line.split()) for line in sheet.breakdown([(key, answers)], by="rim-tear", config=config).splitlines()]
    assert table == ["rim-tear calls right", "photo PR8, 0 plaques 1 1 (100%)", "render, a rim tear 1 0 (0%)",
                     "render, no rim tear 1 1 (100%)"]
    assert sheet.rim_torn_wells(5) == set()  # high draws no tear
