"""Targets, network, loss, polygon NMS and model directories of the segmentation model (hand-made masks)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
import torch.nn.functional as F
from skimage.draw import disk

from platesynth.errors import DatasetError, ParameterError
from platesynth.segment.data import (
    Augmentation,
    augment,
    make_targets,
    normalize_image,
    resize_labels,
    scratch_weights,
)
from platesynth.segment.loss import branch_loss, outside_well_penalty, segmentation_loss
from platesynth.segment.matching import match_instances
from platesynth.segment.model import (
    WELL_RESCALE_RANGE,
    WELL_SIZE_TOLERANCE,
    ModelConfig,
    StarDistTwoBranch,
    load_model,
    save_model,
    select_device,
)
from platesynth.segment.predict import (
    BranchMaps,
    Polygons,
    nms_polygons,
    polygon_diameters,
    polygons_to_mask,
    rescaled_long_side,
)
from platesynth.segment.targets import branch_targets, object_probability, star_distances

TINY = ModelConfig(channels=(4, 8, 8), context_dilations=(2,), input_long_side=64)

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def discs(shape, specs, dtype=np.uint16):
    mask = np.zeros(shape, dtype)
    for i, (y, x, r) in enumerate(specs, start=1):
        mask[disk((y, x), r, shape=shape)] = i
    return mask


def test_star_distances_and_probability_of_a_disc():
    mask = discs((64, 64), [(32, 32, 10)])
    dist = star_distances(mask, n_rays=8)
    assert dist.shape == (64, 64, 8)
    # from the centre every ray runs about one radius; disk() keeps pixel centres strictly inside r
    np.testing.assert_allclose(dist[32, 32], 10.0, atol=1.0)
    assert np.all(dist[mask == 0] == 0)
    prob = object_probability(mask)
    assert prob[32, 32] == pytest.approx(1.0)
    assert prob.max() == pytest.approx(1.0) and np.all(prob[mask == 0] == 0)
    assert 0 < prob[32, 41] < 0.3  # one pixel inside the rim


def test_targets_on_a_grid_and_empty_masks():
    mask = discs((60, 90), [(20, 20, 8), (40, 60, 12)])
    prob, dist = branch_targets(mask, n_rays=16, grid=4)
    assert prob.shape == (15, 23) and dist.shape == (15, 23, 16)
    np.testing.assert_array_equal(prob, object_probability(mask)[::4, ::4])
    np.testing.assert_array_equal(dist, star_distances(mask, 16)[::4, ::4])
    empty_prob, empty_dist = branch_targets(np.zeros((10, 10), np.uint8), n_rays=4, grid=2)
    assert empty_prob.shape == (5, 5) and not empty_prob.any() and not empty_dist.any()
    with pytest.raises(ValueError, match="integer"):
        star_distances(np.zeros((4, 4), np.float32))


def test_network_shapes_and_config_checks():
    model = StarDistTwoBranch(TINY)
    outputs = model(torch.zeros(2, 3, 32, 48))
    assert outputs["wells"][0].shape == (2, 1, 8, 12) and outputs["wells"][1].shape == (2, 32, 8, 12)
    assert outputs["plaques"][0].shape == (2, 1, 16, 24) and outputs["plaques"][1].shape == (2, 32, 16, 24)
    with pytest.raises(ValueError, match="multiples of 4"):
        model(torch.zeros(1, 3, 30, 48))
    with pytest.raises(ValueError, match="power of two"):
        ModelConfig(channels=(8, 16), branches={"wells": {"grid": 4}, "plaques": {"grid": 1}})
    with pytest.raises(ValueError, match="branches"):
        ModelConfig(branches={"wells": {"grid": 1}})


def test_branch_loss_matches_the_stardist_formula():
    generator = torch.Generator().manual_seed(0)
    logits = torch.randn(2, 1, 5, 6, generator=generator)
    dist_pred = torch.rand(2, 4, 5, 6, generator=generator) * 10
    prob_true = torch.rand(2, 1, 5, 6, generator=generator) * (torch.rand(2, 1, 5, 6, generator=generator) > 0.5)
    dist_true = torch.rand(2, 4, 5, 6, generator=generator) * 10 * (prob_true > 0)
    loss, parts = branch_loss(logits, dist_pred, prob_true, dist_true, lambda_dist=0.2, background_reg=1e-4)
    p, d, dp = prob_true.numpy(), dist_true.numpy(), dist_pred.numpy()
    sig = 1 / (1 + np.exp(-logits.numpy()))
    bce = -np.mean(p * np.log(sig) + (1 - p) * np.log(1 - sig))
    dist_term = np.mean(p * np.abs(d - dp)) / np.mean(p)
    reg = np.mean((1 - p) * np.abs(dp))
    assert float(loss) == pytest.approx(bce + 0.2 * (dist_term + 1e-4 * reg), rel=1e-5)
    assert float(parts["dist"]) == pytest.approx(dist_term, rel=1e-5)
    # perfect distances leave only the probability term and the background pull
    exact, exact_parts = branch_loss(logits, dist_true, prob_true, dist_true, 0.2, 0.0)
    assert float(exact_parts["dist"]) == 0.0
    assert float(exact) == pytest.approx(float(F.binary_cross_entropy_with_logits(logits, prob_true)), rel=1e-6)
    # per-pixel weights scale each pixel's probability term; the mean stays over all pixels
    weight = 1 + 9 * (torch.rand(2, 1, 5, 6, generator=generator) > 0.8)
    _, weighted = branch_loss(logits, dist_pred, prob_true, dist_true, 0.2, 1e-4, prob_weight=weight)
    w = weight.numpy()
    assert float(weighted["prob"]) == pytest.approx(-np.mean(w * (p * np.log(sig) + (1 - p) * np.log(1 - sig))), rel=1e-5)
    _, ones = branch_loss(logits, dist_pred, prob_true, dist_true, 0.2, 1e-4, prob_weight=torch.ones_like(weight))
    assert float(ones["prob"]) == pytest.approx(bce, rel=1e-5)


def test_outside_well_penalty_and_total_loss():
    logits = torch.zeros(1, 1, 2, 2)  # probability 0.5 everywhere
    wells = torch.tensor([[[[1.0, 0.0], [0.0, 0.0]]]])
    assert float(outside_well_penalty(logits, wells)) == pytest.approx(0.5 * 3 / 4)
    mask = discs((32, 48), [(16, 12, 7), (16, 36, 7)], np.uint8)
    plaques = discs((32, 48), [(15, 12, 2)])
    targets = {k: v[None] for k, v in make_targets(mask, plaques, TINY).items()}
    outputs = StarDistTwoBranch(TINY)(torch.zeros(1, 3, 32, 48))
    plain, parts = segmentation_loss(outputs, targets)
    penalised, parts_with = segmentation_loss(outputs, targets, within_well_weight=2.0)
    assert parts["total"] == pytest.approx(parts["wells_prob"] + parts["plaques_prob"] + 0.2 * (
        parts["wells_dist"] + parts["plaques_dist"] + 1e-4 * (parts["wells_reg"] + parts["plaques_reg"])), rel=1e-5)
    assert float(penalised.detach()) == pytest.approx(float(plain.detach()) + 2.0 * parts_with["outside_well"], rel=1e-6)
    assert "outside_well" not in parts
    scratches = np.zeros((32, 48), np.float32)
    scratches[20:24, 30:44] = 1.0  # scraped stain beside the second well's middle: only the plaque branch weighs it
    targets = {k: v[None] for k, v in make_targets(mask, plaques, TINY, scratches, 5.0).items()}
    _, weighted = segmentation_loss(outputs, targets)
    assert weighted["plaques_prob"] > parts["plaques_prob"] and weighted["wells_prob"] == parts["wells_prob"]


def test_nms_and_drawing_recover_true_objects_at_another_size():
    # maps made from the true masks at half size must give back the objects at full size
    full = discs((192, 256), [(40, 50, 22), (60, 120, 18), (140, 200, 30), (150, 60, 12)])
    half = resize_labels(full, (96, 128))
    prob, dist = branch_targets(half, n_rays=32, grid=2)
    polygons = nms_polygons(BranchMaps(prob, dist, grid=2), prob_thresh=0.5, nms_thresh=0.3)
    assert len(polygons.points) == 4
    predicted = polygons_to_mask(polygons, (96, 128), full.shape)
    result = match_instances(full, predicted, 0.7)
    assert result.tp == 4 and result.fp == 0
    assert result.iou_r > 0.8
    nothing = nms_polygons(BranchMaps(prob * 0, dist, grid=2), 0.5, 0.3)
    assert not polygons_to_mask(nothing, (96, 128), full.shape).any()


def test_nms_suppresses_overlapping_candidates():
    mask = discs((64, 64), [(32, 32, 15)])
    prob, dist = branch_targets(mask, n_rays=16)
    # every pixel inside the disc is a candidate of about the same polygon: one survives
    flat = BranchMaps(np.where(mask > 0, 0.9, 0.0).astype(np.float32), dist, grid=1)
    assert len(nms_polygons(flat, 0.5, 0.3).points) == 1
    # with NMS off (threshold 1) the candidates all survive
    assert len(nms_polygons(flat, 0.5, 1.0).points) > 100


def test_nms_at_a_low_threshold_contains_the_result_at_a_higher_one():
    # what threshold tuning relies on: polygons are only suppressed by more probable ones
    mask = discs((96, 128), [(30, 30, 12), (34, 44, 12), (70, 90, 20), (20, 100, 8)])
    prob, dist = branch_targets(mask, n_rays=16, grid=2)
    rng = np.random.default_rng(0)
    noisy = BranchMaps((prob * 0.8 + rng.uniform(0, 0.2, prob.shape)).astype(np.float32), dist, grid=2)
    for nms in (0.1, 0.3, 0.5):
        low = nms_polygons(noisy, 0.1, nms)
        for prob_thresh in (0.3, 0.5, 0.7):
            high = nms_polygons(noisy, prob_thresh, nms)
            above = low.scores > prob_thresh
            np.testing.assert_array_equal(high.points, low.points[above])
            np.testing.assert_array_equal(high.scores, low.scores[above])
        assert len(low.points) > len(nms_polygons(noisy, 0.7, nms).points)


def test_augmentation_keeps_image_and_masks_aligned():
    rng = np.random.default_rng(3)
    wells = discs((96, 128), [(48, 40, 20), (48, 90, 20)], np.uint8)
    image = np.where(wells[..., None] > 0, 0.2, 0.9).astype(np.float32) * np.ones(3, np.float32)
    plaques = discs((96, 128), [(48, 40, 5)])
    for _ in range(5):
        out_image, out_wells, out_plaques, none = augment(
            image, wells, plaques, 1.0, (64, 64), Augmentation(noise_sigma=(0, 0)), rng
        )
        assert none is None
        assert out_image.shape == (64, 64, 3) and out_wells.shape == out_plaques.shape == (64, 64)
        assert out_wells.dtype == np.uint8 and out_plaques.dtype == np.uint16
        assert set(np.unique(out_wells)) <= {0, 1, 2}
        if out_wells.any() and (out_wells == 0).any():
            # dark inside wells, bright outside, whatever the geometry and intensity changes
            assert out_image[out_wells > 0].mean() < out_image[out_wells == 0].mean()
        assert np.all(out_wells[out_plaques > 0] > 0)


def test_scratch_map_follows_the_masks_and_leaves_the_draws_as_they_were():
    wells = discs((96, 128), [(48, 40, 20), (48, 90, 20)], np.uint8)
    image = np.where(wells[..., None] > 0, 0.2, 0.9).astype(np.float32) * np.ones(3, np.float32)
    plaques = discs((96, 128), [(48, 40, 5), (40, 95, 8)])
    scratches = (plaques == 2).astype(np.float32)  # a map that marks one plaque: it must stay on it
    for seed in range(6):
        plain = augment(image, wells, plaques, 1.2, (64, 64), Augmentation(), np.random.default_rng(seed))
        out = augment(image, wells, plaques, 1.2, (64, 64), Augmentation(), np.random.default_rng(seed), scratches)
        for a, b in zip(plain[:3], out[:3]):
            np.testing.assert_array_equal(a, b)
        marked, second = out[3] > 0.5, out[2] == 2
        assert out[3].shape == (64, 64) and out[3].dtype == np.float32
        if second.sum() > 20:
            assert (marked & second).sum() / (marked | second).sum() > 0.8


def test_scratch_weights_keep_a_thin_scratch_on_the_grid():
    scratches = np.zeros((9, 12), np.float32)
    scratches[:, 5] = 0.5  # one pixel wide, in an odd column that grid 2 skips
    weights = scratch_weights(scratches, grid=2, weight=10.0)
    assert weights.shape == (5, 6)
    np.testing.assert_allclose(weights[:, 2:4], 6.0)  # cells 2 and 3 stand for columns 4 and 6, beside it
    np.testing.assert_allclose(np.delete(weights, [2, 3], axis=1), 1.0)
    np.testing.assert_array_equal(scratch_weights(scratches, grid=1, weight=4.0)[:, 5], 3.0)


def test_make_targets_weighs_scratches_only_when_asked():
    wells = discs((64, 64), [(32, 32, 25)], np.uint8)
    plaques = discs((64, 64), [(30, 30, 6)])
    scratches = np.zeros((64, 64), np.float32)
    scratches[40:44, 10:50] = 1.0
    assert "plaques_weight" not in make_targets(wells, plaques, TINY)
    assert "plaques_weight" not in make_targets(wells, plaques, TINY, scratches, 0.0)
    weight = make_targets(wells, plaques, TINY, scratches, 3.0)["plaques_weight"]
    grid = TINY.branches["plaques"].grid
    assert tuple(weight.shape) == (1, 64 // grid, 64 // grid)
    assert float(weight.max()) == 4.0 and float(weight.min()) == 1.0
    assert float(weight[0, 42 // grid, 30 // grid]) == 4.0 and float(weight[0, 10 // grid, 30 // grid]) == 1.0


def test_normalisation_uses_joint_percentiles():
    image = np.zeros((10, 10, 3), np.uint8)
    image[..., 0] = np.arange(100).reshape(10, 10)
    normalised = normalize_image(image, 0.0, 100.0)
    assert normalised.min() == 0.0 and normalised.max() == pytest.approx(1.0)
    assert np.all(normalised[..., 1] == 0)
    assert not normalize_image(np.full((4, 4, 3), 7, np.uint8)).any()


def test_model_directory_round_trip_and_errors(tmp_path):
    torch.manual_seed(0)
    model = StarDistTwoBranch(TINY).eval()
    save_model(model, tmp_path / "m")
    loaded = load_model(tmp_path / "m")
    x = torch.rand(1, 3, 32, 32)
    for name in ("wells", "plaques"):
        torch.testing.assert_close(loaded(x)[name][1], model(x)[name][1])
    config = json.loads((tmp_path / "m" / "config.json").read_text())
    assert config["n_rays"] == 32 and config["channels"] == [4, 8, 8] and config["version"]
    with pytest.raises(DatasetError, match="config.json: no such file"):
        load_model(tmp_path / "missing")
    config["channels"] = [4, 8, 16]
    (tmp_path / "m" / "config.json").write_text(json.dumps(config))
    with pytest.raises(DatasetError, match="weights do not load"):
        load_model(tmp_path / "m")
    (tmp_path / "m" / "config.json").write_text("{")
    with pytest.raises(DatasetError, match="not a valid model configuration"):
        load_model(tmp_path / "m")


def test_device_selection():
    assert select_device("cpu").type == "cpu"
    assert select_device("auto").type == ("cuda" if torch.cuda.is_available() else "cpu")
    with pytest.raises(ParameterError, match="unknown device 'tpu'"):
        select_device("tpu")
    if not torch.cuda.is_available():
        with pytest.raises(ParameterError, match="CUDA is not available"):
            select_device("cuda")


def test_polygon_diameters_of_discs_and_squares():
    n_rays = 32
    dist = np.array([np.full(n_rays, 10.0), np.full(n_rays, 3.0)], np.float32)
    polygons = Polygons(np.zeros((2, 2)), dist, np.ones(2, np.float32))
    # a regular polygon of circumradius r has area n r^2 sin(2 pi / n) / 2
    expected = 2 * np.sqrt(n_rays * dist[:, 0] ** 2 * np.sin(2 * np.pi / n_rays) / 2 / np.pi)
    assert polygon_diameters(polygons) == pytest.approx(expected)
    assert polygon_diameters(polygons)[0] == pytest.approx(20.0, rel=0.01)
    # a 20 x 20 square seen from its centre by 4 rays through its corners: area 4 * (10 sqrt 2)^2 / 2 = 400
    corner = 10 * np.sqrt(2)
    square = Polygons(np.zeros((1, 2)), np.full((1, 4), corner, np.float32), np.ones(1, np.float32))
    assert polygon_diameters(square) == pytest.approx([2 * np.sqrt(400 / np.pi)])
    assert len(polygon_diameters(Polygons(np.zeros((0, 2)), np.zeros((0, 8)), np.zeros(0)))) == 0


def test_rescaled_long_side_brings_wells_to_the_training_size():
    def wells(diameter, n=12):
        radius = diameter / 2 / np.sqrt(32 * np.sin(2 * np.pi / 32) / 2 / np.pi)
        return Polygons(np.zeros((n, 2)), np.full((n, 32), radius, np.float32), np.ones(n, np.float32))

    config = ModelConfig(input_long_side=512, well_diameter=100.0)
    assert rescaled_long_side(config, wells(100)) is None
    assert rescaled_long_side(config, wells(100 * (1 + WELL_SIZE_TOLERANCE) - 0.5)) is None  # within tolerance
    assert rescaled_long_side(config, wells(80)) == 640  # wells too small: the image is enlarged by 100/80
    assert rescaled_long_side(config, wells(125)) == 410
    assert rescaled_long_side(config, wells(10)) == 512 * WELL_RESCALE_RANGE[1]  # clamped
    assert rescaled_long_side(config, wells(80, n=0)) is None  # no well found
    assert rescaled_long_side(ModelConfig(input_long_side=512), wells(80)) is None  # a model without the reference


def test_prediction_runs_again_at_the_training_well_size(monkeypatch):
    import platesynth.segment.predict as predict

    model = StarDistTwoBranch(TINY.model_copy(update={"well_diameter": 40.0, "plate_format": 6}))
    calls = []

    def fake_maps(model, image, long_side=None):
        # one well of diameter 20 working pixels at the working size, of 40 at twice that (as a real photo would)
        side = long_side or model.config.input_long_side
        scale = side / model.config.input_long_side
        shape = (round(image.shape[0] * side / max(image.shape[:2])), round(image.shape[1] * side / max(image.shape[:2])))
        calls.append(side)
        maps = {}
        for name, grid in (("wells", 4), ("plaques", 2)):
            prob = np.zeros((-(-shape[0] // grid), -(-shape[1] // grid)), np.float32)
            prob[prob.shape[0] // 2, prob.shape[1] // 2] = 0.9
            radius = 10 * scale / np.sqrt(32 * np.sin(2 * np.pi / 32) / 2 / np.pi)
            maps[name] = BranchMaps(prob, np.full(prob.shape + (32,), radius if name == "wells" else 2 * scale, np.float32), grid)
        return maps, shape

    monkeypatch.setattr(predict, "predict_maps", fake_maps)
    image = np.zeros((96, 128, 3), np.uint8)
    result = predict.predict_image(model, image, thresholds={"wells": (0.5, 0.3), "plaques": (0.5, 0.3)})
    assert calls == [64, 128]  # the well measured 20 working pixels, the model learnt 40: once more at twice the size
    # the masks come from the second pass, drawn at the image's own size: the well is 40 / 128 of its width across
    assert result.wells.shape == (96, 128)
    assert 2 * np.sqrt((result.wells > 0).sum() / np.pi) == pytest.approx(40, rel=0.05)

    calls.clear()
    within = StarDistTwoBranch(TINY.model_copy(update={"well_diameter": 21.0, "plate_format": 6}))
    predict.predict_image(within, image, thresholds={"wells": (0.5, 0.3), "plaques": (0.5, 0.3)})
    assert calls == [64]  # within the tolerance: one pass
