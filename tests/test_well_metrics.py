"""Well-crop metrics: crops, plate grid, power spectrum, plaque size and contrast, set distances, CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from platesynth.cli import app
from platesynth.data.layout import item_paths
from platesynth.data.writer import write_item
from platesynth.errors import MetricUndefinedError, ParameterError, ShapeMismatchError
from platesynth.metrics.wells import (
    WellCrops,
    WellDisc,
    compare_well_crops,
    crop_mask,
    crop_well,
    find_dataset_root,
    fit_plate_grid,
    plaque_area_distance,
    plaque_measurements,
    radial_power_spectrum,
    spectrum_distance,
    well_metrics,
    wells_from_mask,
)
from platesynth.render.result import RenderResult, WellInfo

runner = CliRunner()


def disc(shape, centre, radius):
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
    return np.hypot(rows - centre[0], cols - centre[1]) <= radius


def iou(a, b):
    return (a & b).sum() / (a | b).sum()


def hand_plate(seed=0, shape=(300, 400), angle_deg=0.0, pale=(), stain=(110, 40, 200), plaques_per_well=3):
    """A 3x4 'plate': light plastic, stained textured discs (``pale`` wells nearly clear), light disc plaques.

    Returns the RGB image, the uint8 well mask and the uint16 plaque mask.
    """
    rng = np.random.default_rng(seed)
    height, width = shape
    pitch = min(width / 4.4, height / 3.3)
    radius = 0.425 * pitch
    angle = np.deg2rad(angle_deg)
    image = np.empty((height, width, 3), np.float64)
    image[:] = (228, 230, 240)
    wells = np.zeros(shape, np.uint8)
    plaques = np.zeros(shape, np.uint16)
    top, left = (height - 2 * pitch) / 2, (width - 3 * pitch) / 2
    plaque_id = 0
    for row in range(3):
        for col in range(4):
            dy, dx = row * pitch, col * pitch
            centre = (top + np.cos(angle) * dy + np.sin(angle) * dx, left + np.cos(angle) * dx - np.sin(angle) * dy)
            well_id = 1 + row * 4 + col
            inside = disc(shape, centre, radius)
            wells[inside] = well_id
            colour = (205, 195, 232) if well_id in pale else stain
            image[inside] = colour
            for _ in range(plaques_per_well if well_id not in pale else 0):
                r = rng.uniform(0.15, 0.5) * radius
                offset = rng.uniform(0, radius - r) * np.array([np.cos(t := rng.uniform(0, 2 * np.pi)), np.sin(t)])
                spot = disc(shape, (centre[0] + offset[0], centre[1] + offset[1]), rng.uniform(3, 8)) & inside
                plaque_id += 1
                plaques[spot & (plaques == 0)] = plaque_id
                image[spot] = (225, 215, 240)
    image += rng.normal(0, 6, image.shape)
    return np.clip(image, 0, 255).astype(np.uint8), wells, plaques


# ------------------------------------------------------------------------------------------------ wells and crops


def test_wells_from_mask_gives_bounding_square_and_leaves_out_cut_wells():
    wells = np.zeros((100, 120), np.uint8)
    wells[disc(wells.shape, (40, 50), 20)] = 1
    wells[disc(wells.shape, (50, 110), 15)] = 2  # cut by the right border
    wells[10:21, 80:97] = 3  # a box 11 high, 17 wide
    found = wells_from_mask(wells)
    assert [d.id for d in found] == [1, 3]
    assert found[0] == WellDisc(40.0, 50.0, 20.5, 1)  # bounding box rows 20..60: 41 px
    assert found[1] == WellDisc(15.0, 88.0, 8.5, 3)
    assert [d.id for d in wells_from_mask(wells, keep_cut=True)] == [1, 2, 3]


def test_crop_well_is_the_square_around_the_disc_and_pads_at_the_border():
    image = np.arange(60 * 80 * 3, dtype=np.uint32).reshape(60, 80, 3).astype(np.uint8)
    crop = crop_well(image, WellDisc(30.0, 40.0, 10.0), size=20)  # side 20: no resampling
    assert np.array_equal(crop, image[20:40, 30:50])
    edge = crop_well(image, WellDisc(5.0, 40.0, 10.0), size=20)  # rows -5..14: 5 rows repeated from row 0
    assert np.array_equal(edge[5:], image[0:15, 30:50])
    assert np.array_equal(edge[0], image[0, 30:50])
    assert crop_well(image, WellDisc(30.0, 40.0, 10.0), size=64).shape == (64, 64, 3)
    mask = np.zeros((60, 80), np.uint16)
    mask[25:30, 35:40] = 7
    cropped = crop_mask(mask, WellDisc(30.0, 40.0, 10.0), size=20)
    assert cropped.dtype == bool and cropped.sum() == 25 and cropped[5:10, 5:10].all()


@pytest.mark.parametrize("angle", [0.0, 1.5])
def test_grid_fit_lands_on_the_wells_of_a_drawn_plate(angle):
    image, wells, _ = hand_plate(seed=1, angle_deg=angle, pale=(4, 8))  # two nearly clear wells
    discs = fit_plate_grid(image)
    assert [d.id for d in discs] == list(range(1, 13))
    for found in discs:
        assert iou(disc(wells.shape, (found.cy, found.cx), found.radius), wells == found.id) > 0.95


def test_grid_fit_finds_a_small_plate_and_a_portrait_one():
    image, wells, _ = hand_plate(seed=2)
    frame = np.full((600, 800, 3), 40, np.uint8)  # a dark desk around a plate filling half the frame
    frame[150:450, 200:600] = image
    framed_wells = np.zeros((600, 800), np.uint8)
    framed_wells[150:450, 200:600] = wells
    for found in fit_plate_grid(frame):
        assert iou(disc(framed_wells.shape, (found.cy, found.cx), found.radius), framed_wells == found.id) > 0.9
    portrait = np.ascontiguousarray(np.rot90(image))  # 4 rows x 3 columns now
    found = fit_plate_grid(portrait, (3, 4))
    rotated_wells = np.rot90(wells)
    assert len(found) == 12
    for well in found:
        inside = disc(rotated_wells.shape, (well.cy, well.cx), well.radius)
        assert iou(inside, rotated_wells == np.bincount(rotated_wells[inside]).argmax()) > 0.95


def test_grid_fit_lands_on_the_true_wells_of_a_render():
    from platesynth.render import render
    from platesynth.scene import load_config, sample_scene

    for preset, seed in (("high", 0), ("low", 1)):
        result = render(sample_scene(load_config(preset), seed), (608, 472))
        if result.wells.max() != 12:
            pytest.skip(f"{preset} seed {seed} no longer renders a 12-well plate")
        for found in fit_plate_grid(result.image):
            inside = disc(result.wells.shape, (found.cy, found.cx), found.radius)
            true = result.wells == np.bincount(result.wells[inside]).argmax()
            assert iou(inside, true) > 0.9, (preset, seed, found)


def test_grid_fit_lands_on_the_wells_of_the_real_photos(shared):
    """On real 12-well photos (tight and loose crops) the discs are regular, inside the frame, and on the stain."""
    from platesynth.io import read_image
    from platesynth.metrics.wells import _stain_map

    plates = shared("data", "plaque12", "plates")
    for name in ("Brisbane_plate2", "Brisbane_plate5", "IBV_plate2", "PR8_plate10", "PR8_plate18"):
        image = read_image(plates / f"{name}.jpg")
        discs = fit_plate_grid(image)
        centres = np.array([(d.cy, d.cx) for d in discs]).reshape(3, 4, 2)
        pitch = np.hypot(*np.diff(centres[0], axis=0).T).mean()
        assert 0.40 < discs[0].radius / pitch < 0.45, name  # the 12-well plate: 11.05 mm / 26.01 mm
        stain = _stain_map(image)
        for well in discs:
            assert well.radius <= well.cy <= image.shape[0] - well.radius + 5, name
            assert well.radius <= well.cx <= image.shape[1] - well.radius + 5, name
            inside = disc(stain.shape, (well.cy, well.cx), 0.95 * well.radius)
            ring = disc(stain.shape, (well.cy, well.cx), 1.2 * well.radius) & ~disc(
                stain.shape, (well.cy, well.cx), 1.05 * well.radius
            )
            assert stain[inside].mean() > stain[ring].mean(), (name, well)


# ------------------------------------------------------------------------------------------------- power spectrum


def test_white_noise_has_a_flat_spectrum_at_its_variance():
    rng = np.random.default_rng(0)
    frequencies, _ = radial_power_spectrum(rng.normal(0, 10, (128, 128)))
    assert np.array_equal(frequencies, np.arange(1, 65))
    power = np.mean([radial_power_spectrum(rng.normal(0, 10, (128, 128)))[1] for _ in range(20)], axis=0)
    log_ratio = np.log10(power / 100.0)  # variance 100
    assert np.abs(log_ratio[3:]).max() < 0.05  # flat within 12% from 4 cycles per diameter up
    assert np.abs(log_ratio).max() < 0.15  # the lowest rings lose a little to the mean's removal


@pytest.mark.parametrize("f0", [8, 20, 40])
def test_radial_cosine_peaks_at_its_frequency(f0):
    size = 128
    centre = (size - 1) / 2
    rows, cols = np.mgrid[0:size, 0:size]
    pattern = 100 + 50 * np.cos(2 * np.pi * f0 * np.hypot(rows - centre, cols - centre) / size)
    frequencies, power = radial_power_spectrum(pattern)
    assert frequencies[np.argmax(power)] == f0
    assert power.max() > 1000 * np.median(power)


def test_spectrum_leaves_out_excluded_pixels():
    rng = np.random.default_rng(3)
    noise = rng.normal(0, 10, (128, 128))
    blob = disc(noise.shape, (50, 70), 12)
    with_blob = noise + 150 * blob
    _, kept = radial_power_spectrum(with_blob)
    _, excluded = radial_power_spectrum(with_blob, exclude=blob)
    assert np.log10(kept[:4] / 100).min() > 2  # the bright blob dominates the low frequencies
    assert np.abs(np.log10(excluded / 100)).max() < 0.4  # left out: white noise again


def test_spectrum_of_an_rgb_crop_is_that_of_its_gray_values_and_must_be_square():
    gray = np.random.default_rng(4).integers(0, 256, (64, 64)).astype(np.uint8)
    assert np.array_equal(radial_power_spectrum(np.stack([gray] * 3, -1))[1], radial_power_spectrum(gray)[1])
    with pytest.raises(ShapeMismatchError):
        radial_power_spectrum(np.zeros((64, 48)))


def test_spectrum_distance_is_the_rms_log_difference():
    a = np.linspace(4, 1, 64)
    assert spectrum_distance(a, a) == 0.0
    assert spectrum_distance(a, a + 0.5) == pytest.approx(0.5)
    assert spectrum_distance(a, a + np.r_[np.zeros(48), np.ones(16)]) == pytest.approx(0.5)  # sqrt(16 / 64)


# ------------------------------------------------------------------------------------------------------- plaques


def test_plaque_area_distance_is_in_decades_of_area():
    sizes = np.array([0.001, 0.004, 0.01, 0.03])
    assert plaque_area_distance(sizes, sizes) == 0.0
    assert plaque_area_distance(sizes, 2 * sizes) == pytest.approx(np.log10(2))  # every plaque twice as large
    assert plaque_area_distance([0.001, 0.1], [0.01]) == pytest.approx(1.0)  # one decade either way
    with pytest.raises(MetricUndefinedError, match="no plaques"):
        plaque_area_distance(sizes, [])
    with pytest.raises(MetricUndefinedError, match="positive"):
        plaque_area_distance(sizes, [0.0, 0.01])


def test_plaque_area_and_contrast_of_a_hand_made_mask():
    shape = (120, 200)
    wells = np.zeros(shape, np.uint8)
    wells[disc(shape, (60, 50), 40)] = 1
    wells[disc(shape, (60, 150), 40)] = 2
    plaques = np.zeros(shape, np.uint16)
    plaques[disc(shape, (60, 50), 8)] = 1  # in well 1
    plaques[disc(shape, (60, 150), 5)] = 2  # in well 2
    plaques[disc(shape, (50, 165), 4)] = 3  # in well 2, next to plaque 2: not part of its surroundings
    plaques[5:8, 95:105] = 4  # between the wells: no well, left out
    gray = np.full(shape, 90, np.uint8)
    gray[wells == 1] = 100
    gray[wells == 2] = 80
    gray[plaques == 1] = 200
    gray[plaques == 2] = 120
    gray[plaques == 3] = 250
    image = np.stack([gray] * 3, axis=-1)  # gray RGB: luma = the gray value exactly
    measured = plaque_measurements(image, wells, plaques, well_radius_mm=11.05)
    assert measured["well"].tolist() == [1, 2, 2]
    areas = [int((plaques == i).sum()) for i in (1, 2, 3)]
    assert measured["area_px"].tolist() == areas
    well_areas = [int((wells == w).sum()) for w in (1, 2, 2)]
    assert np.allclose(measured["area_fraction"], np.divide(areas, well_areas))
    assert np.allclose(measured["area_mm2"], measured["area_fraction"] * np.pi * 11.05**2)
    assert np.allclose(measured["contrast"], [(200 - 100) / 100, (120 - 80) / 80, (250 - 80) / 80])


def test_plaque_without_surrounding_monolayer_has_no_contrast():
    wells = np.zeros((40, 40), np.uint8)
    wells[10:30, 10:30] = 1
    plaques = np.zeros((40, 40), np.uint16)
    plaques[10:30, 10:30] = 1  # fills its well
    measured = plaque_measurements(np.full((40, 40), 100, np.uint8), wells, plaques)
    assert measured["area_fraction"].tolist() == [1.0]
    assert np.isnan(measured["contrast"]).all()


# ---------------------------------------------------------------------------------------------------- set metrics


def test_well_crops_measure_masks_and_grids():
    image, wells, plaques = hand_plate(seed=5)
    from_masks, from_grid = WellCrops(size=64), WellCrops(size=64)
    from_masks.update(image, wells, plaques, well_radius_mm=11.05)
    from_grid.update(image)
    masks, grid = from_masks.compute(), from_grid.compute()
    assert masks["n_wells"] == grid["n_wells"] == 12
    assert masks["wells_from"] == "masks" and grid["wells_from"] == "grid"
    assert masks["n_plaques"] == len(np.unique(plaques)) - 1
    truth = plaque_measurements(image, wells, plaques)
    assert masks["plaque_area_fraction_median"] == pytest.approx(np.median(truth["area_fraction"]))
    assert masks["plaque_contrast_mean"] == pytest.approx(np.nanmean(truth["contrast"]))
    assert masks["plaque_area_mm2_median"] == pytest.approx(np.median(truth["area_fraction"]) * np.pi * 11.05**2)
    assert grid["n_plaques"] is None and grid["plaque_contrast_median"] is None  # no mask: not measured
    assert len(masks["spectrum_wells"]) == len(masks["spectrum_frequencies"]) == 32
    assert masks["spectrum_wells"] != masks["spectrum_wells_with_plaques"]  # plaques left out of the first only
    assert grid["spectrum_wells"] == grid["spectrum_wells_with_plaques"]  # no plaque mask: nothing left out
    with pytest.raises(ParameterError):
        WellCrops().update(image, plaques=plaques)


def test_identical_sets_are_at_distance_zero_and_a_changed_set_is_farther(offline_weights, one_torch_thread):
    from platesynth.metrics import get_feature_extractor

    extractor = get_feature_extractor("alexnet")

    def crops_of(seeds, transform=lambda image: image):
        crops = WellCrops(size=64, extractor=extractor)
        for image, wells, plaques in (hand_plate(seed) for seed in seeds):
            crops.update(transform(image), wells, plaques)
        return crops

    def noisier(image):
        noise = np.random.default_rng(9).normal(0, 25, image.shape)
        return np.clip(image + noise, 0, 255).astype(np.uint8)

    reference = crops_of(range(3))
    same = compare_well_crops(crops_of(range(3)), reference)
    assert same["fd_wells"] == pytest.approx(0.0, abs=1e-6)
    assert same["kid_wells"] <= 0.0  # the unbiased MMD² of a set with itself is slightly negative
    assert same["dnf_wells"] == 0.0 and same["spectrum_distance_wells"] == 0.0
    assert same["spectrum_distance_wells_with_plaques"] == 0.0
    assert same["plaque_area_distance"] == 0.0 and same["plaque_contrast_distance"] == 0.0

    alike = compare_well_crops(crops_of(range(3, 6)), reference)  # other plates of the same kind
    changed = compare_well_crops(crops_of(range(3), noisier), reference)  # noise 6 -> 26 gray levels
    assert 0 < alike["fd_wells"] < changed["fd_wells"] / 2
    assert abs(alike["kid_wells"]) * 100 < changed["kid_wells"]
    assert same["nn_accuracy_wells"] == 0.0  # each crop's nearest neighbour is its copy in the other set
    assert changed["nn_accuracy_wells"] == 1.0 and alike["nn_accuracy_wells"] < 1.0  # noise sets them apart
    assert alike["spectrum_distance_wells"] < 0.1 and changed["spectrum_distance_wells"] > 0.5
    assert alike["dnf_wells"] < 0.05 and changed["dnf_wells"] > 0.2
    assert 0 < alike["plaque_area_distance"] < 0.1  # other random plaques of the same size range
    assert json.dumps(changed, allow_nan=False)


def test_well_metrics_of_a_dataset_against_photos(tmp_path):
    dataset, photos = tmp_path / "synthetic", tmp_path / "photos"
    photos.mkdir()
    for index in range(2):
        image, wells, plaques = hand_plate(seed=10 + index)
        info = [WellInfo(i, (i - 1) // 4, (i - 1) % 4, f"W{i}") for i in range(1, 13)]
        write_item(item_paths(dataset, f"{index:06d}"), RenderResult(image, wells, plaques, info),
                   {"scene": {"plate": {"well_radius_mm": 11.05}}})
        Image.fromarray(hand_plate(seed=20 + index, stain=(90, 50, 180))[0]).save(photos / f"photo{index}.png")
    assert find_dataset_root(dataset) == find_dataset_root(dataset / "images") == dataset
    assert find_dataset_root(photos) is None
    seen = []
    result = well_metrics(dataset / "images", photos, size=64, frechet=False, progress=lambda *a: seen.append(a))
    assert result["n_wells"] == result["n_wells_reference"] == 24
    assert result["wells_from"] == "masks" and result["wells_from_reference"] == "grid"
    assert result["plaque_area_mm2_median"] > 0 and result["plaque_area_mm2_median_reference"] is None
    assert result["plaque_area_distance"] is None and result["plaque_contrast_distance"] is None
    assert "fd_wells" not in result
    assert result["spectrum_distance_wells"] > 0 and result["dnf_wells"] >= 0
    assert json.dumps(result, allow_nan=False)
    assert seen[0][1:] == (0, 2) and seen[-1][1:] == (2, 2)

    cli = runner.invoke(
        app, ["metrics", "dataset", str(dataset), "--reference", str(photos), "--wells", "--well-size", "64",
              "--no-frechet", "--json"]
    )
    assert cli.exit_code == 0, cli.output
    printed = json.loads(cli.stdout)
    assert printed["n_images"] == 2 and printed["spectrum_distance_wells"] == pytest.approx(
        result["spectrum_distance_wells"]
    )
    table = runner.invoke(app, ["metrics", "dataset", str(dataset), "--reference", str(photos), "--wells",
                                "--well-size", "64", "--no-frechet"])
    assert table.exit_code == 0 and "dnf_wells" in table.stdout and "spectrum_wells" not in table.stdout
    refused = runner.invoke(app, ["metrics", "dataset", str(dataset), "--wells"])
    assert refused.exit_code == 1 and refused.stdout == "" and "--reference" in refused.stderr


def test_a_model_gives_the_wells_and_plaques_of_photos_without_masks(tmp_path, one_torch_thread):
    from pathlib import Path

    from platesynth.metrics.wells import collect_well_crops
    from platesynth.render import render
    from platesynth.scene import load_config, sample_scene

    model = Path(__file__).resolve().parents[1] / "models" / "plaque12"
    if not (model / "weights.pt").is_file():
        pytest.skip(f"{model}: the shipped model is missing")
    photos = tmp_path / "photos"
    photos.mkdir()
    Image.fromarray(render(sample_scene(load_config("high"), 2), (608, 472)).image).save(photos / "plate.png")
    crops = collect_well_crops(photos, size=64, model=model).compute()
    assert crops["wells_from"] == "model"
    assert 8 <= crops["n_wells"] <= 12
    assert crops["n_plaques"] is not None  # measured from the predicted plaque masks
