"""The dataset layout: writer, reader, counts.csv, COCO, resume and refusal (hand-made render results)."""

from __future__ import annotations

import functools
import json
import os

import numpy as np
import pytest
import tifffile
from PIL import Image

from platesynth.data.batch import build_manifest, item_seed, render_dataset, rerender
from platesynth.data.coco import PLAQUE_CATEGORY, WELL_CATEGORY, coco_dataset, decode_rle, encode_rle
from platesynth.data.executor import ProcessExecutor
from platesynth.data.layout import (
    COUNTS_COLUMNS,
    Manifest,
    is_finished,
    item_name,
    item_paths,
    list_items,
    load_item,
    read_counts_csv,
    read_manifest,
)
from platesynth.data.preview import contact_sheet, draw_outlines
from platesynth.data.writer import (
    check_directory,
    finished_items,
    prepare_directory,
    remove_dataset_files,
    write_counts_csv,
    write_item,
)
from platesynth.errors import DatasetError, EmptyDatasetError, ParameterError, RenderError
from platesynth.render.result import RenderResult, WellInfo, plaque_counts


def disc(shape, center, radius):
    yy, xx = np.mgrid[: shape[0], : shape[1]]
    return (yy - center[0]) ** 2 + (xx - center[1]) ** 2 <= radius**2


def fake_result(seed: int, shape=(60, 80)) -> RenderResult:
    """A 2x3 'plate': six disc wells, a few random disc plaques (some straddling two wells)."""
    rng = np.random.default_rng(seed)
    wells = np.zeros(shape, np.uint8)
    info = []
    for row in range(2):
        for col in range(3):
            well_id = row * 3 + col + 1
            wells[disc(shape, (15 + 30 * row, 14 + 26 * col), 12)] = well_id
            info.append(WellInfo(well_id, row, col, f"{'AB'[row]}{3 - col}"))
    plaques = np.zeros(shape, np.uint16)
    for plaque_id in range(1, int(rng.integers(3, 9)) + 1):
        center = (int(rng.integers(3, shape[0] - 3)), int(rng.integers(3, shape[1] - 3)))
        plaques[disc(shape, center, int(rng.integers(1, 4))) & (plaques == 0)] = plaque_id
    image = rng.integers(0, 256, (*shape, 3), dtype=np.uint8)
    return RenderResult(image=image, wells=wells, plaques=plaques, well_info=info)


def write_fake_dataset(directory, count=3, seed=0, coco=False, overwrite=False):
    manifest = Manifest(
        platesynth_version="test", config={"a": 1}, seed=seed, count=count, size=(80, 60), backend="fake", coco=coco
    )
    manifest, todo = prepare_directory(directory, manifest, overwrite=overwrite)
    for index in todo:
        write_item(item_paths(directory, item_name(index)), fake_result(seed * 1000 + index), {"index": index})
    return manifest, todo


def test_write_item_layout_dtypes_and_params(tmp_path):
    result = fake_result(1)
    item = item_paths(tmp_path, "000000")
    write_item(item, result, {"seed": 5})
    assert [p.relative_to(tmp_path).as_posix() for p in item.paths()] == [
        "images/000000.png",
        "masks/wells/000000.tif",
        "masks/plaques/000000.tif",
        "params/000000.json",
    ]
    assert np.array_equal(np.asarray(Image.open(item.image_path)), result.image)
    wells, plaques = tifffile.imread(item.wells_path), tifffile.imread(item.plaques_path)
    assert wells.dtype == np.uint8 and plaques.dtype == np.uint16
    assert np.array_equal(wells, result.wells) and np.array_equal(plaques, result.plaques)
    params = json.loads(item.params_path.read_text())
    assert params["seed"] == 5
    counts = result.plaque_counts()
    assert [(w["id"], w["row"], w["col"], w["label"], w["count"]) for w in params["wells"]] == [
        (w.id, w.row, w.col, w.label, counts[w.id]) for w in result.well_info
    ]
    assert not list(tmp_path.rglob(".*"))  # no temporary file left


def test_write_item_rejects_wrong_dtypes(tmp_path):
    result = fake_result(1)
    result.plaques = result.plaques.astype(np.int32)
    with pytest.raises(DatasetError, match="uint16"):
        write_item(item_paths(tmp_path, "000000"), result, {})
    assert not (tmp_path / "images").exists()


def test_list_and_load_items(tmp_path):
    write_fake_dataset(tmp_path, count=3)
    items = list_items(tmp_path)
    assert [item.name for item in items] == ["000000", "000001", "000002"]
    image, wells, plaques = load_item(items[1])
    expected = fake_result(1)
    assert image.dtype == np.uint8 and image.shape == (60, 80, 3)
    assert np.array_equal(wells, expected.wells) and np.array_equal(plaques, expected.plaques)


def test_list_items_errors(tmp_path):
    with pytest.raises(EmptyDatasetError, match="no images/ folder"):
        list_items(tmp_path)
    write_fake_dataset(tmp_path, count=2)
    item = item_paths(tmp_path, "000001")
    item.plaques_path.unlink()
    with pytest.raises(DatasetError, match=r"000001\.tif: missing mask"):
        list_items(tmp_path)


def test_load_item_size_mismatch(tmp_path):
    write_fake_dataset(tmp_path, count=1)
    item = item_paths(tmp_path, "000000")
    tifffile.imwrite(item.wells_path, np.zeros((10, 10), np.uint8))
    with pytest.raises(DatasetError, match="mask size 10x10 differs from image"):
        load_item(item)


def test_counts_csv_matches_masks(tmp_path):
    write_fake_dataset(tmp_path, count=3)
    items = finished_items(tmp_path, 3)
    path = write_counts_csv(tmp_path, items)
    rows = read_counts_csv(path)
    assert len(rows) == 3 * 6
    assert path.read_text().splitlines()[0] == ",".join(COUNTS_COLUMNS)
    for item in items:
        image, wells, plaques = load_item(item)
        from_masks = plaque_counts(wells, plaques)
        mine = {(r.row, r.col): r.count for r in rows if r.image == item.image_path.name}
        assert mine == {((i - 1) // 3, (i - 1) % 3): n for i, n in from_masks.items()}
    assert sum(r.count for r in rows) > 0


def test_read_counts_csv_blank_and_errors(tmp_path):
    good = tmp_path / "good.csv"
    good.write_text("image,row,col,well,count\na.jpg,0,3,A1,\na.jpg,0,2,A2,42\n")
    assert read_counts_csv(good) == [("a.jpg", 0, 3, "A1", None), ("a.jpg", 0, 2, "A2", 42)]
    missing = tmp_path / "missing.csv"
    missing.write_text("image,row,well,count\na.jpg,0,A1,3\n")
    with pytest.raises(DatasetError, match="missing column"):
        read_counts_csv(missing)
    bad = tmp_path / "bad.csv"
    bad.write_text("image,row,col,well,count\na.jpg,0,1,A1,many\n")
    with pytest.raises(DatasetError, match="line 2"):
        read_counts_csv(bad)
    with pytest.raises(DatasetError, match="no such file"):
        read_counts_csv(tmp_path / "nope.csv")


def test_read_real_counts_csv(shared):
    rows = read_counts_csv(shared("data", "plaque12", "counts.csv"))
    assert len(rows) == 468
    assert sum(r.count is not None for r in rows) == 402


def test_resume_skips_finished_and_cleans_temporary_files(tmp_path):
    manifest, todo = write_fake_dataset(tmp_path, count=4)
    assert todo == [0, 1, 2, 3]
    item = item_paths(tmp_path, "000002")
    item.params_path.unlink()  # as if killed before the params were written
    temporary = tmp_path / "images" / ".000003.abc.tmp.png"
    temporary.write_bytes(b"partial")
    _, todo = prepare_directory(tmp_path, manifest)
    assert todo == [2]
    assert not temporary.exists()
    assert not is_finished(item)


def test_extend_and_refuse_shrink(tmp_path):
    manifest, _ = write_fake_dataset(tmp_path, count=2)
    _, todo = prepare_directory(tmp_path, manifest.model_copy(update={"count": 4}))
    assert todo == [2, 3]
    with pytest.raises(DatasetError, match="extended but not shrunk"):
        check_directory(tmp_path, manifest.model_copy(update={"count": 1}))


def test_refuse_different_dataset_unless_overwrite(tmp_path):
    write_fake_dataset(tmp_path, count=2, seed=0)
    (tmp_path / "notes.txt").write_text("mine")
    before = sorted(p.name for p in tmp_path.rglob("*"))
    with pytest.raises(DatasetError, match=r"different dataset \(seed differ\)"):
        write_fake_dataset(tmp_path, count=2, seed=1)
    assert sorted(p.name for p in tmp_path.rglob("*")) == before
    _, todo = write_fake_dataset(tmp_path, count=1, seed=1, overwrite=True)
    assert todo == [0]
    assert (tmp_path / "notes.txt").read_text() == "mine"
    assert [i.name for i in list_items(tmp_path)] == ["000000"]
    assert read_manifest(tmp_path).seed == 1


def test_overwrite_resumes_the_same_dataset_and_replaces_a_broken_one(tmp_path):
    manifest, _ = write_fake_dataset(tmp_path, count=2)
    _, todo = prepare_directory(tmp_path, manifest, overwrite=True)
    assert todo == [] and len(list_items(tmp_path)) == 2
    (tmp_path / "manifest.json").write_text("{}")
    with pytest.raises(DatasetError, match="not a valid platesynth manifest"):
        check_directory(tmp_path, manifest)
    _, todo = prepare_directory(tmp_path, manifest, overwrite=True)
    assert todo == [0, 1] and read_manifest(tmp_path) == manifest


def test_refuse_foreign_directory_and_file(tmp_path):
    (tmp_path / "photo.jpg").write_bytes(b"x")
    manifest = Manifest(platesynth_version="t", config={}, seed=0, count=1, size=(80, 60), backend="fake")
    with pytest.raises(DatasetError, match="holds no platesynth dataset"):
        check_directory(tmp_path, manifest)
    target = tmp_path / "photo.jpg"
    with pytest.raises(DatasetError, match="is not a directory"):
        check_directory(target, manifest, overwrite=True)


def test_remove_dataset_files_keeps_other_files(tmp_path):
    write_fake_dataset(tmp_path, count=2)
    (tmp_path / "images" / "keep.png").write_bytes(b"x")
    remove_dataset_files(tmp_path)
    assert sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*")) == ["images", "images/keep.png"]


def test_invalid_manifest_is_a_clear_error(tmp_path):
    (tmp_path / "manifest.json").write_text("{not json")
    with pytest.raises(DatasetError, match="manifest.json: not a valid platesynth manifest"):
        read_manifest(tmp_path)


@pytest.mark.parametrize("shape", [(7, 5), (1, 1), (4, 9)])
def test_rle_round_trip(shape):
    rng = np.random.default_rng(shape[0])
    for mask in (rng.random(shape) > 0.5, np.zeros(shape, bool), np.ones(shape, bool)):
        rle = encode_rle(mask)
        assert rle["size"] == list(shape)
        assert sum(rle["counts"]) == mask.size
        assert np.array_equal(decode_rle(rle), mask)
    mask = np.zeros(shape, bool)
    mask[0, 0] = True
    assert encode_rle(mask)["counts"][:2] == [0, 1]  # runs start with background, column-major


def test_rle_of_a_crop_equals_rle_of_the_whole():
    mask = disc((30, 40), (12, 20), 6)
    crop = mask[6:19, 14:27]
    assert encode_rle(crop, offset=(6, 14), shape=(30, 40)) == encode_rle(mask)


def test_coco_matches_masks(tmp_path):
    write_fake_dataset(tmp_path, count=2)
    items = list_items(tmp_path)
    coco = coco_dataset(items)
    assert [c["name"] for c in coco["categories"]] == ["well", "plaque"]
    assert [im["id"] for im in coco["images"]] == [1, 2]
    assert [a["id"] for a in coco["annotations"]] == list(range(1, len(coco["annotations"]) + 1))
    for image_entry, item in zip(coco["images"], items, strict=True):
        _, wells, plaques = load_item(item)
        assert (image_entry["width"], image_entry["height"]) == (80, 60)
        mine = [a for a in coco["annotations"] if a["image_id"] == image_entry["id"]]
        for category, mask in ((WELL_CATEGORY, wells), (PLAQUE_CATEGORY, plaques)):
            annotations = [a for a in mine if a["category_id"] == category]
            assert sorted(a["instance_id"] for a in annotations) == [int(i) for i in np.unique(mask) if i]
            for a in annotations:
                expected = mask == a["instance_id"]
                assert np.array_equal(decode_rle(a["segmentation"]), expected)
                assert a["area"] == int(expected.sum())
                rows, cols = np.nonzero(expected)
                assert a["bbox"] == [cols.min(), rows.min(), cols.max() - cols.min() + 1, rows.max() - rows.min() + 1]


def test_contact_sheet_and_outlines():
    results = [fake_result(i) for i in range(5)]
    tiles = [draw_outlines(r.image, r.wells, r.plaques) for r in results]
    no_plaques = draw_outlines(results[0].image, results[0].wells, np.zeros_like(results[0].plaques))
    rows, cols = np.nonzero(results[0].wells == 1)
    leftmost = rows[cols.argmin()], cols.min()
    assert tuple(no_plaques[leftmost]) == (255, 210, 0)
    assert np.array_equal(no_plaques[30, 40], results[0].image[30, 40])  # between wells: untouched
    sheet = contact_sheet(tiles, columns=3, tile_width=40, gap=2)
    assert sheet.dtype == np.uint8 and sheet.shape == (2 + 2 * (30 + 2), 2 + 3 * (40 + 2), 3)
    assert (sheet[:2] == 255).all() and (sheet[-2:] == 255).all()


# --- the real renderer, through render_dataset -------------------------------------------------------------

SMALL = {"preset": "high", "seed": 3, "size": (160, 120)}


def tree_bytes(directory) -> dict[str, bytes]:
    """Every file under ``directory`` by relative path (the manifest too)."""
    return {p.relative_to(directory).as_posix(): p.read_bytes() for p in sorted(directory.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """A 3-image dataset with COCO, rendered once for the tests that only read it."""
    directory = tmp_path_factory.mktemp("rendered")
    summary = render_dataset(directory, build_manifest(count=3, coco=True, **SMALL))
    return directory, summary


def test_render_dataset_files_ids_and_counts(rendered):
    directory, summary = rendered
    assert (summary.rendered, summary.skipped, summary.failed) == (3, 0, {})
    items = list_items(directory)
    assert [item.name for item in items] == ["000000", "000001", "000002"]
    rows = read_counts_csv(directory / "counts.csv")
    assert len(rows) == 3 * 12
    for item in items:
        image, wells, plaques = load_item(item)
        assert image.shape == (120, 160, 3) and wells.dtype == np.uint8 and plaques.dtype == np.uint16
        params = json.loads(item.params_path.read_text())
        assert sorted(w["id"] for w in params["wells"]) == list(range(1, 13))
        assert set(np.unique(wells)) == set(range(13))
        plaque_ids = np.unique(plaques)[1:]
        assert np.array_equal(plaque_ids, np.arange(1, plaque_ids.size + 1))  # 1..m without gaps
        by_grid = {(w["row"], w["col"]): w["id"] for w in params["wells"]}
        from_masks = plaque_counts(wells, plaques)
        # a person's count: the plaques in the masks, blank (None) for a lysed or emptied well
        uncountable = {w["id"] for w in params["scene"]["wells"] if w["lysed"] or w["emptied"]}
        mine = {(r.row, r.col): r.count for r in rows if r.image == f"{item.name}.png"}
        assert mine == {pos: None if i in uncountable else from_masks[i] for pos, i in by_grid.items()}
        assert all(w["plaques"] == from_masks[w["id"]] for w in params["wells"])
    assert sum(r.count or 0 for r in rows) > 0
    assert any(r.count is None for r in rows)  # this small dataset holds a lysed or emptied well
    manifest = read_manifest(directory)
    assert (manifest.count, manifest.seed, manifest.size, manifest.failed) == (3, 3, (160, 120), {})


def test_params_rerender_byte_identical(rendered, tmp_path):
    directory, _ = rendered
    item = list_items(directory)[2]
    params = json.loads(item.params_path.read_text())
    assert params["seed"] == item_seed(3, 2) and params["index"] == 2 and params["size"] == [160, 120]
    again = rerender(item)
    copy = item_paths(tmp_path, item.name)
    write_item(copy, again, {key: value for key, value in params.items() if key != "wells"})
    for original, new in zip(item.paths(), copy.paths(), strict=True):
        assert original.read_bytes() == new.read_bytes(), original.name


def test_item_seeds_are_independent():
    seeds = [item_seed(3, i) for i in range(100)]
    assert len(set(seeds)) == 100 and all(0 <= s < 2**63 for s in seeds)
    assert item_seed(3, 5) == item_seed(3, 5) != item_seed(4, 5)


def test_coco_of_rendered_dataset(rendered):
    directory, _ = rendered
    coco = json.loads((directory / "annotations.coco.json").read_text())
    assert len(coco["images"]) == 3
    wells = [a for a in coco["annotations"] if a["category_id"] == WELL_CATEGORY]
    assert len(wells) == 36
    _, _, plaques = load_item(list_items(directory)[0])
    first = [a for a in coco["annotations"] if a["image_id"] == 1 and a["category_id"] == PLAQUE_CATEGORY]
    assert len(first) == int(plaques.max())
    assert sum(a["area"] for a in first) == int((plaques > 0).sum())


def test_resume_after_crash_and_deleted_item(rendered, tmp_path):
    source, _ = rendered
    directory = tmp_path / "ds"
    render_dataset(directory, build_manifest(count=3, coco=True, **SMALL))
    expected = tree_bytes(directory)
    assert expected == tree_bytes(source)  # a second run in another directory gives the same bytes
    item = item_paths(directory, "000001")
    for path in item.paths():
        path.unlink()
    item_paths(directory, "000002").params_path.unlink()  # killed before its params were written
    leftover = directory / "masks" / "wells" / ".000002.x1y2.tmp.tif"
    leftover.write_bytes(b"partial")
    progress = []
    summary = render_dataset(
        directory, build_manifest(count=3, coco=True, **SMALL), progress=lambda done, total: progress.append(done)
    )
    assert (summary.rendered, summary.skipped) == (2, 1)
    assert progress == [1, 2, 3]
    assert tree_bytes(directory) == expected


def test_extend_gives_the_same_images(rendered, tmp_path):
    source, _ = rendered
    render_dataset(tmp_path, build_manifest(count=2, **SMALL))
    summary = render_dataset(tmp_path, build_manifest(count=3, **SMALL))
    assert (summary.rendered, summary.skipped) == (1, 2)
    mine, theirs = tree_bytes(tmp_path), tree_bytes(source)
    for name in mine:
        if name != "manifest.json":
            assert mine[name] == theirs[name], name


def test_failed_item_is_recorded_and_retried(tmp_path, monkeypatch):
    import platesynth.data.batch as batch

    calls = []
    real_render = batch.render

    def flaky_render(scene, size, backend):
        calls.append(1)
        if len(calls) == 2:
            raise RenderError("the renderer broke")
        return real_render(scene, size=size, backend=backend)

    monkeypatch.setattr(batch, "render", flaky_render)
    summary = render_dataset(tmp_path, build_manifest(count=3, **SMALL))
    assert summary.failed == {"000001": "RenderError: the renderer broke"}
    assert read_manifest(tmp_path).failed == summary.failed
    assert {r.image for r in read_counts_csv(tmp_path / "counts.csv")} == {"000000.png", "000002.png"}
    assert not item_paths(tmp_path, "000001").image_path.exists()
    summary = render_dataset(tmp_path, build_manifest(count=3, **SMALL))
    assert (summary.rendered, summary.skipped, summary.failed) == (1, 2, {})
    assert read_manifest(tmp_path).failed == {}


def test_a_failure_records_the_renderers_log_in_the_manifest(tmp_path, monkeypatch):
    import platesynth.data.batch as batch

    class LoggedError(RenderError):
        def __init__(self) -> None:
            super().__init__("Blender failed: out of memory")
            self.log = "line 1 of the log\nError: out of memory"

    def broken_render(scene, size, backend):
        raise LoggedError()

    monkeypatch.setattr(batch, "render", broken_render)
    summary = render_dataset(tmp_path, build_manifest(count=1, **SMALL))
    error = read_manifest(tmp_path).failed["000000"]
    assert error == summary.failed["000000"]
    assert error.splitlines()[0] == "LoggedError: Blender failed: out of memory"
    assert error.endswith("line 1 of the log\nError: out of memory")

def mark_worker(directory) -> None:
    """Worker setup used by the tests: leaves a file named after the worker's process id."""
    (directory / str(os.getpid())).write_text("set up")


def test_processes_equal_serial_and_run_setup(rendered, tmp_path):
    source, _ = rendered
    marks = tmp_path / "marks"
    marks.mkdir()
    with ProcessExecutor(workers=2, setup=functools.partial(mark_worker, marks)) as executor:
        summary = render_dataset(tmp_path / "ds", build_manifest(count=3, coco=True, **SMALL), executor=executor)
    assert summary.rendered == 3
    assert tree_bytes(tmp_path / "ds") == tree_bytes(source)
    workers = {int(p.name) for p in marks.iterdir()}
    assert 1 <= len(workers) <= 2 and os.getpid() not in workers


def test_build_manifest_rejects_bad_values():
    with pytest.raises(ParameterError, match="count must be > 0"):
        build_manifest(count=0)
    with pytest.raises(ParameterError, match="seed must be >= 0"):
        build_manifest(count=1, seed=-1)
    with pytest.raises(ParameterError, match="unknown backend 'povray'"):
        build_manifest(count=1, backend="povray")
    with pytest.raises(ParameterError, match="unknown preset"):
        build_manifest(count=1, preset="nope")
