"""Training, resuming, prediction and evaluation of the segmentation model on a few rendered images, and the CLI."""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import shutil

import numpy as np
import pytest
import tifffile
import torch
from typer.testing import CliRunner

from platesynth.cli import app
from platesynth.data.layout import list_items, load_item, read_counts_csv
from platesynth.errors import DatasetError
from platesynth.render.raster import scratch_map
from platesynth.render.result import RenderResult
from platesynth.scene import load_scene
from platesynth.segment.counts import evaluate_counts, sort_wells
from platesynth.segment.data import SegmentationDataset, pad_to_multiple, scratch_weights
from platesynth.segment.loss import segmentation_loss
from platesynth.segment.matching import evaluate_masks
from platesynth.segment.model import ModelConfig, StarDistTwoBranch, UnfinishedModelError, load_model
from platesynth.segment.train import (
    CHECKPOINT_NAME,
    ThresholdScores,
    TrainConfig,
    choose_thresholds,
    mask_statistics,
    one_standard_error_choice,
    split_items,
    threshold_scores,
    train,
    tuning_items,
    validation_items,
)

runner = CliRunner()
TINY = ModelConfig(channels=(8, 12, 16), context_dilations=(2,), input_long_side=128)

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def invoke(*args: str):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """Four small rendered 12-well plates (the renderer's own masks and counts.csv)."""
    out = tmp_path_factory.mktemp("rendered") / "data"
    result = invoke("render", "--out", out, "--count", 4, "--seed", 5, "--preset", "high", "--plate", 12, "--size", "128x96")
    assert result.exit_code == 0, result.output
    return out


@pytest.fixture(scope="module")
def tiny_model(rendered, tmp_path_factory):
    model_dir = tmp_path_factory.mktemp("model") / "tiny"
    config = TrainConfig(data=[str(rendered)], epochs=1, steps_per_epoch=2, batch_size=2, patch=(64, 64), val_fraction=0.25)
    train(config, model_dir, TINY)
    return model_dir


def test_loss_falls_on_rendered_images(rendered):
    torch.manual_seed(0)
    dataset = SegmentationDataset(list_items(rendered), TINY, patch=(64, 64), augmentation=None, seed=1)
    batch = {k: torch.stack([dataset[(i, 0)][k] for i in range(4)]) for k in dataset[0]}
    model = StarDistTwoBranch(TINY)
    optimizer = torch.optim.Adam(model.parameters(), lr=3e-3)
    losses = []
    for _ in range(25):
        loss, _ = segmentation_loss(model(batch["image"]), batch)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        losses.append(float(loss.detach()))
    assert losses[-1] < 0.6 * losses[0]


def test_scratch_weights_come_from_each_items_scene(rendered, tmp_path):
    items = list_items(rendered)
    weighted = SegmentationDataset(items, TINY, scratch_weight=10.0)
    grid = TINY.branches["plaques"].grid
    scraped_somewhere = False
    for index, item in enumerate(items):
        sample = weighted[index]
        scraped = scratch_map(load_scene(item.params_path), (128, 96))  # the working size: no resizing
        expected = scratch_weights(pad_to_multiple(scraped, TINY.size_multiple), grid, 10.0)
        np.testing.assert_allclose(sample["plaques_weight"][0].numpy(), expected, rtol=1e-6)
        scraped_somewhere |= bool((expected > 2).any())
        plain = SegmentationDataset(items, TINY)[index]
        assert "plaques_weight" not in plain and torch.equal(plain["plaques_prob"], sample["plaques_prob"])
    assert scraped_somewhere
    # a photo (no scene) weighs every pixel 1
    photos = _copy(rendered, tmp_path)
    shutil.rmtree(photos / "params")
    (photos / "manifest.json").unlink()
    sample = SegmentationDataset(list_items(photos), TINY, scratch_weight=10.0)[0]
    assert torch.all(sample["plaques_weight"] == 1.0)


class _Stop(Exception):
    pass


def test_training_resumes_to_the_same_weights(rendered, tmp_path):
    config = TrainConfig(
        data=[str(rendered)], epochs=2, steps_per_epoch=2, batch_size=2, patch=(64, 64), val_fraction=0.25, tune_thresholds=False
    )
    straight = train(config, tmp_path / "straight", TINY)
    assert straight.epochs_done == 2 and straight.resumed_from_epoch == 0

    def stop_after_first_epoch(event):
        if event.get("epoch") == 1 and "val_loss" in event:
            raise _Stop

    with pytest.raises(_Stop):
        train(config, tmp_path / "resumed", TINY, progress=stop_after_first_epoch)
    # a training started before a setting existed resumes where that setting is at its default
    saved_identity = json.loads((tmp_path / "resumed" / "train.json").read_text())
    del saved_identity["train"]["min_resolved_cells"]
    (tmp_path / "resumed" / "train.json").write_text(json.dumps(saved_identity))
    # the interrupted training is no model yet: loading it says where it stopped and how to resume
    assert json.loads((tmp_path / "resumed" / "config.json").read_text())["complete"] is False
    with pytest.raises(UnfinishedModelError, match=r"unfinished training \(stopped during epoch 2 of 2\); resume it"):
        load_model(tmp_path / "resumed")
    assert load_model(tmp_path / "resumed", allow_unfinished=True).config.complete is False
    resumed = train(config, tmp_path / "resumed", TINY)
    assert load_model(tmp_path / "resumed").config.complete is True
    assert resumed.resumed_from_epoch == 1 and resumed.epochs_done == 2
    # checkpoints hold tensors and plain data only: they load with weights_only=True
    first = torch.load(tmp_path / "straight" / CHECKPOINT_NAME, weights_only=True)["model"]
    second = torch.load(tmp_path / "resumed" / CHECKPOINT_NAME, weights_only=True)["model"]
    assert all(torch.equal(first[k], second[k]) for k in first)
    assert [h["train_loss"] for h in straight.history] == [h["train_loss"] for h in resumed.history]

    # the model directory describes its training data; the baseline is the training images' mean count
    saved = json.loads((tmp_path / "straight" / "config.json").read_text())
    train_items, val_items = split_items(list_items(rendered), 0.25, config.seed)
    names = {item.image_path.name for item in train_items}
    # over every well's masks: lysed and emptied wells (blank in counts.csv) hold no plaque
    counts = [w.count or 0 for w in read_counts_csv(rendered / "counts.csv") if w.image in names]
    assert saved["training"]["mean_plaques_per_well"] == pytest.approx(np.mean(counts))
    assert saved["training"]["sources"][0]["n_train"] == len(train_items) == 3
    assert saved["training"]["sources"][0]["preset"] == "high"

    with pytest.raises(DatasetError, match="different training .differs in train seed"):
        train(config.model_copy(update={"seed": 1}), tmp_path / "straight", TINY)
    with pytest.raises(DatasetError, match="differs in model channels"):
        train(config, tmp_path / "straight", TINY.model_copy(update={"channels": (8, 12, 24)}))


def _oracle(rendered, drop_plaque_in=None):
    """A predictor that returns the true masks of the rendered image it is given.

    With ``drop_plaque_in``, one plaque is removed from the first well holding any (in images that have plaques).
    """
    truth = {}
    for item in list_items(rendered):
        image, wells, plaques = load_item(item)
        blank = {(w["row"], w["col"]) for w in json.loads(item.params_path.read_text())["wells"] if w["count"] is None}
        truth[hashlib.sha1(image.tobytes()).hexdigest()] = (wells, plaques, blank)

    def predict(image):
        wells, plaques, blank = truth[hashlib.sha1(image.tobytes()).hexdigest()]
        sorted_wells, info = sort_wells(wells, 12, from_below=True)
        info = [dataclasses.replace(w, countable=(w.row, w.col) not in blank) for w in info]
        result = RenderResult(image, sorted_wells, plaques.copy(), info)
        counts = result.plaque_counts()
        if drop_plaque_in is not None and any(counts.values()):
            well = next(w for w in info if counts[w.id] > 0)
            victim = np.unique(plaques[(sorted_wells == well.id) & (plaques > 0)])[0]
            result.plaques[result.plaques == victim] = 0
        return result

    return predict


def test_evaluate_counts_with_known_counts(rendered):
    table = read_counts_csv(rendered / "counts.csv")
    scored = [w for w in table if w.count is not None]
    report = evaluate_counts(_oracle(rendered), rendered / "images", rendered / "counts.csv", 12, baseline_count=2.0)
    assert len(table) == 48 and 0 < len(scored) < 48  # the blanks: lysed or emptied wells
    assert report["n_wells"] == len(scored) and report["n_images"] == 4
    assert report["mae"] == 0.0 and report["rmse"] == 0.0 and report["n_wells_not_detected"] == 0
    assert report["pearson_r"] == pytest.approx(1.0)
    truth = [w.count for w in scored]
    assert report["baseline"]["mae"] == pytest.approx(np.mean(np.abs(np.array(truth) - 2.0)))
    # every listed well has a record; blank wells' masks hold no plaque
    assert sorted((w["image"], w["row"], w["col"], w["predicted"]) for w in report["wells"]) == sorted(
        (w.image, w.row, w.col, w.count or 0) for w in table
    )
    # the oracle judges countability as the renderer did
    assert report["countability"]["n_wells"] == 48 and report["countability"]["n_uncountable"] == 48 - len(scored)
    assert report["countability"]["precision"] == report["countability"]["recall"] == report["countability"]["accuracy"] == 1.0
    # one plaque fewer on every image with plaques: each such image has one well off by one
    with_plaques = len({w.image for w in scored if w.count})
    assert with_plaques >= 1
    off = evaluate_counts(_oracle(rendered, drop_plaque_in=True), rendered / "images", rendered / "counts.csv", 12)
    n = len(scored)
    assert off["mae"] == pytest.approx(with_plaques / n) and off["bias"] == pytest.approx(-with_plaques / n)


def test_evaluate_masks_with_true_masks(rendered):
    report = evaluate_masks(_oracle(rendered), rendered, taus=(0.5, 0.9))
    assert report["n_images"] == 4
    for name in ("wells", "plaques"):
        assert report[name]["0.9"]["ap_mean"] == 1.0
        assert report[name]["0.9"]["fp"] == 0 and report[name]["0.9"]["fn"] == 0
    assert report["wells"]["0.5"]["n_true"] == 48


def test_cli_train_predict_evaluate(rendered, tiny_model, tmp_path):
    config = load_model(tiny_model).config
    assert config.training["thresholds_tuned_on"] == 1
    assert config.training["recipe"]["min_resolved_cells"] == 0.0  # every rendered plaque scored, kept with the model
    at_thresholds = config.training["validation_at_thresholds"]  # the held-out image's count error, kept
    assert 0 < at_thresholds["countable_wells"] <= 12 and at_thresholds["count_mae"] >= abs(at_thresholds["count_bias"])

    out = tmp_path / "pred"
    images = sorted((rendered / "images").glob("*.png"))[:2]
    # an untrained model finds candidates everywhere: high thresholds keep NMS short
    fast = ("--well-prob", 0.7, "--plaque-prob", 0.7, "--plaque-nms", 0.3)
    result = invoke("predict", *images, "--model", tiny_model, "--out", out, *fast)
    assert result.exit_code == 0, result.output
    for image in images:
        wells = tifffile.imread(out / "masks" / "wells" / f"{image.stem}.tif")
        plaques = tifffile.imread(out / "masks" / "plaques" / f"{image.stem}.tif")
        assert wells.shape == plaques.shape == (96, 128)
        assert wells.dtype == np.uint8 and plaques.dtype == np.uint16
        params = json.loads((out / "params" / f"{image.stem}.json").read_text())
        assert params["thresholds"] == {"wells": [0.7, config.branches["wells"].nms_thresh], "plaques": [0.7, 0.3]}
        assert [w["id"] for w in params["wells"]] == sorted(int(i) for i in np.unique(wells) if i)
        rows = [r for r in csv.DictReader((out / "counts.csv").open()) if r["image"] == image.name]
        assert [(int(r["row"]), int(r["col"]), r["well"], r["count"]) for r in rows] == [
            (w["row"], w["col"], w["label"], "" if w["count"] is None else str(w["count"])) for w in params["wells"]
        ]

    result = invoke("evaluate", "masks", "--model", tiny_model, "--data", rendered, "--tau", 0.5, "--tau", 0.7, "--json", *fast)
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["n_images"] == 4 and set(report["plaques"]) == {"0.5", "0.7"}
    assert report["wells"]["0.5"]["n_true"] == 48

    result = invoke(
        "evaluate", "counts", "--model", tiny_model, "--images", rendered / "images", "--counts", rendered / "counts.csv",
        "--json", "--table", tmp_path / "wells.csv",
    )
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    n_counted = sum(w.count is not None for w in read_counts_csv(rendered / "counts.csv"))
    assert report["n_wells"] == n_counted < 48  # blank (uncountable) wells are not scored...
    assert report["countability"]["n_uncountable"] == 48 - n_counted - sum(
        not w["detected"] and w["count"] is None for w in report["wells"])  # ...but judged, where detected
    assert report["baseline"]["count"] == pytest.approx(config.training["mean_plaques_per_well"])
    assert len(list(csv.DictReader((tmp_path / "wells.csv").open()))) == 48  # every listed well


def _copy(rendered, tmp_path):
    data = tmp_path / "data"
    shutil.copytree(rendered, data)
    return data


def test_cli_bad_training_data(rendered, tmp_path):
    data = _copy(rendered, tmp_path)
    (data / "masks" / "plaques" / "000002.tif").unlink()
    result = invoke("train", "--data", data, "--out", tmp_path / "m", "--epochs", 1, "--steps", 1)
    assert result.exit_code == 1
    assert "000002.tif: missing mask" in result.output and "Traceback" not in result.output
    assert not (tmp_path / "m").exists()

    data = _copy(rendered, tmp_path / "other")
    tifffile.imwrite(data / "masks" / "wells" / "000001.tif", np.zeros((90, 128), np.uint8))
    result = invoke("train", "--data", data, "--out", tmp_path / "m2", "--epochs", 1, "--steps", 1, "--batch-size", 4,
                    "--patch", "64x64", "--val-fraction", 0)
    assert result.exit_code == 1
    assert "000001.tif: mask size 128x90 differs from image" in result.output
    assert not (tmp_path / "m2").exists()

    result = invoke("train", "--data", rendered, "--out", tmp_path / "m3", "--mix", "0.9,0.1")
    assert result.exit_code == 1 and "--mix has 2 fractions for 1 datasets" in result.output

    result = invoke("train", "--data", rendered, "--out", tmp_path / "m4", "--min-resolved-cells", -1)
    assert result.exit_code == 1 and "min_resolved_cells" in result.output and not (tmp_path / "m4").exists()


def test_cli_bad_counts_and_images(rendered, tiny_model, tmp_path):
    rows = (rendered / "counts.csv").read_text().splitlines()
    unknown = tmp_path / "unknown.csv"
    unknown.write_text("\n".join(rows[:3] + ["000000.png,5,1,F3,2"]) + "\n")
    result = invoke("evaluate", "counts", "--model", tiny_model, "--images", rendered / "images", "--counts", unknown)
    assert result.exit_code == 1
    assert "unknown.csv, line 4: unknown well F3 at row 5, col 1" in result.output

    missing = tmp_path / "missing.csv"
    missing.write_text("\n".join(rows[:2] + ["nowhere.jpg,0,0,A4,3"]) + "\n")
    result = invoke("evaluate", "counts", "--model", tiny_model, "--images", rendered / "images", "--counts", missing)
    assert result.exit_code == 1 and "not found" in result.output and "nowhere.jpg" in result.output

    broken = tmp_path / "broken.png"
    broken.write_bytes(b"not an image")
    good = rendered / "images" / "000000.png"
    result = invoke("predict", good, broken, "--model", tiny_model, "--out", tmp_path / "pred")
    assert result.exit_code == 1 and "broken.png: cannot read image" in result.output
    assert not (tmp_path / "pred").exists()

    result = invoke("predict", good, "--model", tmp_path / "no-model", "--out", tmp_path / "pred")
    assert result.exit_code == 1 and "config.json: no such file" in result.output


def test_one_standard_error_choice():
    # candidate 2 has the smallest mean error (1.0); its standard error is sd([0, 2, 0, 2]) / 2 = 0.577
    errors = [[4, 4, 4, 4], [1, 2, 1, 2], [0, 2, 0, 2], [1, 1, 1, 2]]
    assert one_standard_error_choice(errors, default=0) == 1  # 1.5 <= 1.0 + 0.577: the first within reach
    assert one_standard_error_choice([[3, 3], [1, 1], [1, 1]], default=0) == 1  # no spread: the first best
    assert one_standard_error_choice([[], []], default=1) == 1  # no countable well: the default


def test_choose_thresholds():
    mean_ap = {"wells": np.array([[0.2, 0.9, 0.4], [0.1, 0.3, 0.95]]), "plaques": np.array([[0.5, 0.6, 0.4], [0.3, 0.2, 0.1]])}
    # predicted minus true plaques in four wells per (probability, NMS): the plaques' best AP is at probability 0.3
    count_errors = np.array([
        [[-4, -4, -4, -4], [-1, -2, 1, -2], [0, 2, 0, -2]],
        [[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]],
    ], float)
    scores = ThresholdScores((0.3, 0.5), (0.3, 0.5, 0.7), mean_ap, count_errors)
    # |errors| at 0.3: means 4, 1.5, 1.0; 1.5 is within one standard error (0.577) of 1.0, so NMS 0.5
    assert choose_thresholds(scores) == {"wells": (0.5, 0.7), "plaques": (0.3, 0.5)}


@pytest.mark.parametrize("min_cells", [0.0, 1.0])
def test_threshold_scores_match_drawing_each_pair(rendered, tiny_model, min_cells):
    """The scores read off one drawing per NMS threshold equal those of drawing each pair's polygons alone, with
    every rendered plaque scored (0) or the unresolvable ones left out with the predictions lying on them."""
    from platesynth.render.result import plaque_counts
    from platesynth.segment.countability import rendered_countable
    from platesynth.segment.matching import match_instances
    from platesynth.segment.predict import nms_polygons, polygons_to_mask, predict_maps
    from platesynth.segment.resolvable import lying_on, resolvable_plaques

    model = load_model(tiny_model)
    items = list_items(rendered)[:2]
    # the barely trained model's probabilities lie in a narrow band: candidate thresholds inside it
    band = predict_maps(model, load_item(items[0])[0])[0]["plaques"].prob
    probs, nms = tuple(float(p) for p in np.percentile(band, [50, 90, 99])), (0.3, 0.5)
    scores = threshold_scores(model, items, probs, nms, min_resolved_cells=min_cells)
    mean_ap = np.zeros((3, 2))
    errors = [[[] for _ in nms] for _ in probs]
    left_out, truths = 0, []
    for item in items:
        image, wells, plaques = load_item(item)
        resolved, unresolved = resolvable_plaques(plaques, 1.0, 2, min_cells)  # 128 px images: the working size
        left_out += unresolved.size
        counted = [w for w, ok in rendered_countable(item).items() if ok]
        maps, working_shape = predict_maps(model, image)
        truths += [plaque_counts(wells, resolved, counted)[w] for w in counted]
        for i, prob in enumerate(probs):
            for j, nms_thresh in enumerate(nms):
                predicted = polygons_to_mask(nms_polygons(maps["plaques"], prob, nms_thresh), working_shape, wells.shape)
                predicted[lying_on(predicted, plaques, unresolved)[predicted]] = 0
                mean_ap[i, j] += match_instances(resolved, predicted, 0.5).ap / len(items)
                found, true = plaque_counts(wells, predicted, counted), plaque_counts(wells, resolved, counted)
                errors[i][j] += [found[w] - true[w] for w in counted]
    assert (left_out > 0) == (min_cells > 0)
    assert np.abs(errors).sum() > 0 and len(np.unique(np.array(errors).sum(axis=-1))) > 1  # the thresholds matter
    np.testing.assert_array_equal(scores.count_errors, np.array(errors, float))
    np.testing.assert_array_equal(scores.true_counts, np.array(truths, float))
    assert scores.true_counts.sum() > 0
    np.testing.assert_allclose(scores.mean_ap["plaques"], mean_ap, rtol=1e-12)
    assert scores.mean_ap["wells"].shape == (3, 2) and 0 <= scores.mean_ap["wells"].min() <= scores.mean_ap["wells"].max() <= 1


def test_tuning_items_are_the_held_out_renders_the_training_tuned_on(rendered, tiny_model, tmp_path):
    model = load_model(tiny_model)
    held_out = split_items(list_items(rendered), 0.25, 0)[1]  # the fixture's val_fraction and seed
    assert held_out and tuning_items(model, tiny_model) == held_out
    moved = tmp_path / "moved"
    shutil.copytree(rendered, moved)
    elsewhere = tuning_items(model, tiny_model, [moved])
    assert [item.name for item in elsewhere] == [item.name for item in held_out]
    assert all(item.image_path.parent.parent == moved for item in elsewhere)
    # a model without train.json (the shipped one) is read from the recipe its config.json records
    bare = tmp_path / "bare"
    bare.mkdir()
    for name in ("config.json", "weights.pt"):
        shutil.copy2(tiny_model / name, bare / name)
    assert tuning_items(model, bare) == held_out


def test_validation_items_take_each_source_in_turn():
    sources = [["h1", "h2", "h3", "h4"], ["m1"], ["d1", "d2"]]
    assert validation_items(sources, 4) == ["h1", "m1", "d1", "h2"]  # every source before a second of any
    assert validation_items(sources, 99) == ["h1", "m1", "d1", "h2", "d2", "h3", "h4"]  # all, none twice
    assert validation_items([[], ["m1"]], 3) == ["m1"]


def test_mask_statistics_and_the_trained_models_well_diameter(rendered, tiny_model):
    items = list_items(rendered)
    mean_plaques, diameter = mask_statistics(items, long_side=64)
    counts, diameters = [], []
    for item in items:
        _, wells, plaques = load_item(item)
        counts += RenderResult(np.zeros(wells.shape + (3,), np.uint8), wells, plaques, sort_wells(wells, 12)[1]).plaque_counts().values()
        diameters += [2 * np.sqrt((wells == i).sum() / np.pi) * 64 / 128 for i in np.unique(wells) if i]
    assert mean_plaques == pytest.approx(np.mean(counts))
    assert diameter == pytest.approx(np.median(diameters))
    assert 10 < diameter < 16  # 12-well plates filling a 64-pixel-wide frame: wells about 13 pixels across
    # the model learns it from its training items at its working size (128 pixels)
    config = load_model(tiny_model).config
    train_items = split_items(items, 0.25, 0)[0]
    assert config.well_diameter == pytest.approx(mask_statistics(train_items, 128)[1])
