"""Mask metrics (IoU, Hungarian matching, AP, IoU_R), count metrics and sorting wells into the plate grid."""

from __future__ import annotations

import math

import numpy as np
import pytest
from skimage.draw import disk

from platesynth.errors import ShapeMismatchError
from platesynth.segment.counts import CountMetrics, grid_positions, sort_wells, well_label
from platesynth.segment.matching import InstanceMetrics, iou_matrix, match_from_iou, match_instances


def boxes(shape, *rects):
    """Instance mask with rectangle i+1 = (row0, row1, col0, col1)."""
    mask = np.zeros(shape, np.int32)
    for i, (r0, r1, c0, c1) in enumerate(rects, start=1):
        mask[r0:r1, c0:c1] = i
    return mask


def test_iou_matrix_hand_computed():
    true = boxes((10, 10), (0, 4, 0, 4), (6, 10, 6, 10))  # two 16-px squares
    pred = boxes((10, 10), (0, 4, 2, 6))  # 16 px, shares 8 with true 1
    iou, true_ids, pred_ids = iou_matrix(true, pred)
    assert true_ids.tolist() == [1, 2] and pred_ids.tolist() == [1]
    np.testing.assert_allclose(iou, [[8 / 24], [0.0]])


def test_iou_matrix_non_consecutive_ids_and_shape_check():
    true = np.zeros((4, 4), np.uint16)
    true[:2, :2] = 7
    pred = np.zeros((4, 4), np.int32)
    pred[:2, :2] = 3
    iou, true_ids, pred_ids = iou_matrix(true, pred)
    assert (true_ids.tolist(), pred_ids.tolist(), iou.tolist()) == ([7], [3], [[1.0]])
    with pytest.raises(ShapeMismatchError):
        iou_matrix(true, pred[:3])


def test_perfect_and_partial_match():
    true = boxes((10, 10), (0, 4, 0, 4), (6, 10, 6, 10))
    result = match_instances(true, true, 0.5)
    assert (result.tp, result.fp, result.fn, result.ap, result.iou_r) == (2, 0, 0, 1.0, 1.0)
    # one prediction shifted by one column (IoU 12/20), one true object missed
    pred = boxes((10, 10), (0, 4, 1, 5))
    result = match_instances(true, pred, 0.5)
    assert (result.tp, result.fp, result.fn) == (1, 0, 1)
    assert result.ap == pytest.approx(1 / 2)
    assert result.iou_r == pytest.approx((12 / 20) / 2)
    assert result.pairs == ((1, 1),)
    # at tau 0.7 the shifted prediction no longer counts
    strict = match_instances(true, pred, 0.7)
    assert (strict.tp, strict.fp, strict.fn, strict.ap, strict.iou_r) == (0, 1, 2, 0.0, 0.0)


def test_no_predictions_no_true_objects_and_both_empty():
    true = boxes((8, 8), (0, 3, 0, 3), (4, 8, 4, 8))
    empty = np.zeros((8, 8), np.int32)
    no_pred = match_instances(true, empty)
    assert (no_pred.tp, no_pred.fp, no_pred.fn, no_pred.ap, no_pred.iou_r) == (0, 0, 2, 0.0, 0.0)
    no_true = match_instances(empty, true)
    assert (no_true.tp, no_true.fp, no_true.fn, no_true.ap) == (0, 2, 0, 0.0)
    assert math.isnan(no_true.iou_r)
    nothing = match_instances(empty, empty)
    assert nothing.ap == 1.0 and math.isnan(nothing.iou_r)


def test_duplicate_predictions_count_once():
    true = boxes((10, 10), (0, 4, 0, 4))
    pred = np.zeros((10, 10), np.int32)
    pred[0:4, 0:4] = 1  # exact copy: IoU 1
    duplicate = boxes((10, 10), (0, 4, 0, 3))  # 12 px inside the true object: IoU 0.75
    iou = np.concatenate([iou_matrix(true, pred)[0], iou_matrix(true, duplicate)[0]], axis=1)
    result = match_from_iou(iou, 0.5)
    assert (result.tp, result.fp, result.fn) == (1, 1, 0)
    assert result.ap == pytest.approx(1 / 2)
    assert result.iou_sum == pytest.approx(1.0)  # the better of the two is kept
    assert result.iou_r == pytest.approx(1.0)


def test_hungarian_maximises_the_number_of_pairs():
    # Greedy (best IoU first) pairs true 1 with pred 1 and leaves two objects unmatched; the optimum has two pairs.
    iou = np.array([[0.6, 0.5], [0.4, 0.0]])
    result = match_from_iou(iou, 0.3)
    assert result.tp == 2
    assert sorted(result.pairs) == [(1, 2), (2, 1)]
    assert result.iou_sum == pytest.approx(0.9)
    assert result.iou_r == pytest.approx(0.45)


def test_tau_out_of_range():
    with pytest.raises(ValueError, match="tau"):
        match_from_iou(np.zeros((1, 1)), 0.0)
    with pytest.raises(ValueError, match="tau"):
        InstanceMetrics(taus=(1.5,))


def test_instance_metrics_mean_and_spread_over_images():
    true = boxes((10, 10), (0, 4, 0, 4), (6, 10, 6, 10))
    metric = InstanceMetrics(taus=(0.5, 0.9))
    metric.update(true, true)  # AP 1, IoU_R 1
    metric.update(true, boxes((10, 10), (0, 4, 1, 5)))  # AP 1/2, IoU_R 0.3 at 0.5; AP 0, IoU_R 0 at 0.9
    metric.update(np.zeros((10, 10), int), np.zeros((10, 10), int))  # AP 1, IoU_R undefined
    summary = metric.compute()
    at_half = summary["0.5"]
    assert at_half["ap_mean"] == pytest.approx(np.mean([1, 0.5, 1]))
    assert at_half["ap_std"] == pytest.approx(np.std([1, 0.5, 1]))
    assert at_half["iou_r_mean"] == pytest.approx(np.mean([1, 0.3]))
    assert at_half["iou_r_std"] == pytest.approx(np.std([1, 0.3]))
    assert (at_half["n_images"], at_half["n_images_iou_r"]) == (3, 2)
    assert (at_half["tp"], at_half["fp"], at_half["fn"]) == (3, 0, 1)
    assert summary["0.9"]["ap_mean"] == pytest.approx(np.mean([1, 0, 1]))
    metric.reset()
    assert math.isnan(metric.compute()["0.5"]["ap_mean"])


def test_count_metrics_hand_computed():
    metric = CountMetrics()
    metric.update([0, 2, 5], [1, 2, 3])
    metric.update([10], [10])
    result = metric.compute()
    assert result["n_wells"] == 4
    assert result["mae"] == pytest.approx((1 + 0 + 2 + 0) / 4)
    assert result["rmse"] == pytest.approx(math.sqrt((1 + 0 + 4 + 0) / 4))
    assert result["bias"] == pytest.approx((-1 + 0 + 2 + 0) / 4)
    assert result["pearson_r"] == pytest.approx(np.corrcoef([0, 2, 5, 10], [1, 2, 3, 10])[0, 1])
    constant = CountMetrics()
    constant.update([3, 3], [1, 2])
    assert math.isnan(constant.compute()["pearson_r"])
    assert CountMetrics().compute()["n_wells"] == 0
    with pytest.raises(ValueError):
        metric.update([1], [1, 2])


def grid_centres(rows, cols, spacing, angle_deg, origin=(200.0, 150.0)):
    angle = math.radians(angle_deg)
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    y0, x0 = r.ravel() * spacing, c.ravel() * spacing
    y = origin[0] + y0 * math.cos(angle) + x0 * math.sin(angle)
    x = origin[1] + x0 * math.cos(angle) - y0 * math.sin(angle)
    return np.stack([y, x], axis=1), r.ravel(), c.ravel()


@pytest.mark.parametrize("angle", [-7.0, 0.0, 4.0])
def test_grid_positions_rotated_shuffled_with_missing_wells(angle):
    centres, rows, cols = grid_centres(3, 4, 100.0, angle)
    rng = np.random.default_rng(1)
    centres = centres + rng.normal(0, 3, centres.shape)
    keep = np.ones(12, bool)
    keep[[0, 6]] = False  # the top-left well and one in the middle are not found
    order = rng.permutation(np.flatnonzero(keep))
    found_rows, found_cols = grid_positions(centres[order])
    # the top-left well is missing but its row and column still hold other wells
    assert found_rows.tolist() == rows[order].tolist()
    assert found_cols.tolist() == cols[order].tolist()


def test_grid_positions_skip_a_missing_column():
    centres, rows, cols = grid_centres(3, 4, 100.0, 0.0)
    keep = cols != 1
    found_rows, found_cols = grid_positions(centres[keep])
    assert found_cols.tolist() == cols[keep].tolist()
    assert found_rows.tolist() == rows[keep].tolist()


def test_sort_wells_numbers_by_grid_drops_small_and_extra_rows():
    shape = (520, 560)
    wells = np.zeros(shape, np.uint8)
    centres, rows, cols = grid_centres(4, 4, 120.0, 0.0, origin=(80.0, 90.0))
    ids = np.arange(16)[::-1] + 1  # reverse reading order
    for (y, x), well_id in zip(centres, ids):
        wells[disk((y, x), 45, shape=shape)] = well_id
    wells[disk((500, 540), 8, shape=shape)] = 40  # a small speck
    wells[wells == ids[3]] = 0  # the first row is a partly visible second plate: keep the 3 fullest rows
    wells[wells == ids[1]] = 0
    sorted_mask, info = sort_wells(wells, plate_format=12, from_below=True)
    assert sorted_mask.dtype == np.uint8
    assert [(w.id, w.row, w.col) for w in info] == [(i + 1, i // 4, i % 4) for i in range(12)]
    assert [w.label for w in info[:4]] == ["A4", "A3", "A2", "A1"]
    # well 1 of the sorted mask is the one at grid position (1, 0) of the drawn 4x4 grid
    y, x = centres[4]
    assert sorted_mask[int(y), int(x)] == 1
    assert sorted_mask[500, 540] == 0
    assert sorted_mask[int(centres[0][0]), int(centres[0][1])] == 0


def test_well_labels():
    assert well_label(0, 0, 4, from_below=True) == "A4"
    assert well_label(2, 3, 4, from_below=True) == "C1"
    assert well_label(1, 0, 4, from_below=False) == "B1"
