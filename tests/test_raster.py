"""The raster renderer, its masks, the mask clean-up and the post-processing effects."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from _geometry import distance_to_top_edges, past_top_edge, pixel_centres_mm, wall_band
from platesynth.errors import ParameterError, ShapeMismatchError
from platesynth.render import postprocess as pp
from platesynth.render import render
from platesynth.render.appearance import draw_well_content, stain_table, wall_sheen, wall_tints
from platesynth.render.color import srgb_to_linear
from platesynth.render.look import (
    CRESCENT_LIGHT,
    WALL_HIGHLIGHT_PLACES,
    WALL_LINE_PLACES,
    WALL_LINE_WOBBLE_MM,
    wall_line_phase,
)
from platesynth.render.masks import clean_isolated_pixels
from platesynth.render.raster import camera_view, parallax, plate_relief, render_raster, scratch_map, wells_in_view
from platesynth.render.result import plaque_counts, plaque_wells
from platesynth.render.sampling import ring, smeared_ring
from platesynth.render.textures import scene_textures
from platesynth.scene import Scene, load_config, sample_scene
from platesynth.scene.concrete import Plaque

SMALL = (256, 192)


def small_scene(preset: str = "high", seed: int = 1, **overrides) -> Scene:
    return sample_scene(load_config(preset, overrides=overrides or None), seed)


def test_same_scene_gives_byte_identical_arrays():
    scene = small_scene("high", 3)
    first = render(scene, SMALL)
    again = render_raster(Scene.model_validate(scene.model_dump(mode="json")), SMALL)
    for name in ("image", "wells", "plaques"):
        assert getattr(first, name).tobytes() == getattr(again, name).tobytes()
    other = render(small_scene("high", 4), SMALL)
    assert other.image.tobytes() != first.image.tobytes()


def test_masks_have_the_promised_types_and_ids():
    scene = small_scene("high", 2, **{"plaques.negative_plate": 0.0, "plaques.top_count": 300})
    result = render(scene, SMALL)
    assert result.image.shape == (192, 256, 3) and result.image.dtype == np.uint8
    assert result.wells.shape == (192, 256) and result.wells.dtype == np.uint8
    assert result.plaques.shape == (192, 256) and result.plaques.dtype == np.uint16
    plaque_ids = np.unique(result.plaques)
    assert plaque_ids[0] == 0 and list(plaque_ids[1:]) == list(range(1, len(plaque_ids)))
    assert len(plaque_ids) > 5
    assert set(np.unique(result.wells)) - {0} <= {w.id for w in scene.wells}
    assert [(w.id, w.row, w.col, w.label) for w in result.well_info] == [
        (w.id, w.row, w.col, w.label) for w in scene.wells
    ]
    # every plaque pixel lies inside a well, and each plaque in one well only
    assert np.all(result.wells[result.plaques > 0] > 0)
    pairs = np.unique(np.stack([result.plaques[result.plaques > 0], result.wells[result.plaques > 0]]), axis=1)
    assert len(np.unique(pairs[0])) == pairs.shape[1]


def test_counts_from_masks_equal_the_scene_when_no_plaque_is_hidden():
    overrides = {"plaques.max_overlap": 0.0, "plaques.radius_mm": [0.8, 1.2], "plaques.negative_plate": 0.0,
                 "plaques.top_count": 40, "plaques.lysis_count": 1000, "plaques.irregularity": 0.0}
    scene = small_scene("high", 5, **overrides)
    result = render(scene, (320, 240))
    expected = {w.id: 0 for w in scene.wells}
    for plaque in scene.plaques:
        expected[plaque.well] += 1
    assert sum(expected.values()) > 10
    assert result.plaque_counts() == expected


def _with_plaques(scene: Scene, plaques: list[tuple[float, float, float]]) -> Scene:
    """The scene with its plaques replaced by round ones ``(dx, dy, radius)`` mm around well 1's centre."""
    well = next(w for w in scene.wells if w.id == 1)
    made = tuple(
        Plaque(id=i + 1, well=1, center_mm=(well.center_mm[0] + dx, well.center_mm[1] + dy), radius_mm=r,
               fourier=(), softness=0.2, clearness=0.9)
        for i, (dx, dy, r) in enumerate(plaques)
    )
    return scene.model_copy(update={"plaques": made})


def test_hidden_plaques_are_absent_and_the_topmost_wins():
    base = small_scene("low", 1, **{"wells.emptied": 0.0})
    # plaque 1 lies wholly under plaque 2; plaque 3 is partly covered by plaque 4
    scene = _with_plaques(base, [(0.0, 0.0, 1.0), (0.0, 0.0, 2.5), (6.0, 0.0, 2.0), (8.0, 0.0, 2.0)])
    result = render(scene, (512, 384))
    assert sorted(np.unique(result.plaques)) == [0, 1, 2, 3]
    view = camera_view(scene, 512, 384)
    centre = view.project(np.array(next(w.center_mm for w in scene.wells if w.id == 1))).astype(int)
    assert result.plaques[centre[1], centre[0]] == 1  # the covering plaque, renumbered first
    between = view.project(np.array([scene.plaques[2].center_mm[0] + 1.5, scene.plaques[2].center_mm[1]]))
    assert result.plaques[int(between[1]), int(between[0])] == 3  # overlap goes to the later plaque
    assert result.plaque_counts()[1] == 3


def test_plaques_are_clipped_to_their_well():
    base = small_scene("low", 1, **{"wells.emptied": 0.0})
    radius = base.plate.well_radius_mm
    scene = _with_plaques(base, [(radius - 0.5, 0.0, 3.0)])
    result = render(scene, (512, 384))
    plaque = result.plaques == 1
    assert plaque.any()
    assert np.all(result.wells[plaque] == 1)
    wider = render(_with_plaques(base, [(radius - 3.5, 0.0, 3.0)]), (512, 384))
    assert plaque.sum() < (wider.plaques == 1).sum()


@pytest.mark.parametrize("fmt", [6, 12, 24, 96])
def test_every_plate_format_renders_all_wells(fmt):
    scene = small_scene("diverse", 2, **{"plate.format": fmt, "camera.plate_fill": 0.9, "camera.offset": 0.0,
                                         "camera.tilt_deg": 0.0})
    result = render(scene, SMALL)
    assert sorted(np.unique(result.wells))[1:] == list(range(1, fmt + 1))
    # ids run row-major over the image grid: well 1 top-left, well n bottom-right
    ys, xs = np.nonzero(result.wells == 1)
    ye, xe = np.nonzero(result.wells == fmt)
    assert ys.mean() < ye.mean() and xs.mean() < xe.mean()


def test_from_below_mirrors_the_plate():
    below = small_scene("low", 3, **{"camera.from_below": 1.0})
    result = render(below, SMALL)
    a1 = next(w.id for w in below.wells if w.label == "A1")
    a4 = next(w.id for w in below.wells if w.label == "A4")
    assert np.nonzero(result.wells == a1)[1].mean() > np.nonzero(result.wells == a4)[1].mean()


def test_stained_wells_are_purple_and_the_plate_bright():
    scene = small_scene("low", 4, **{"wells.emptied": 0.0, "plaques.negative_plate": 1.0})
    result = render(scene, SMALL)
    inside = result.image[result.wells > 0].astype(float)
    red, green, blue = inside.mean(axis=0)
    assert blue > red > green and blue - green > 80
    outside = result.image[result.wells == 0].astype(float).mean(axis=0)
    assert outside.mean() > inside.mean() + 40


def test_any_resolution_keeps_the_geometry():
    scene = small_scene("low", 6)
    small = render(scene, (200, 150))
    large = render(scene, (400, 300))
    assert abs((large.wells > 0).mean() - (small.wells > 0).mean()) < 0.01
    assert np.unique(small.wells).tolist() == np.unique(large.wells).tolist()


def test_bad_size_and_backend_are_refused():
    scene = small_scene("low", 1)
    with pytest.raises(ParameterError, match="size"):
        render(scene, (0, 10))
    with pytest.raises(ParameterError, match="unknown backend 'povray'"):
        render(scene, SMALL, backend="povray")


def test_a_smeared_ring_is_as_dark_in_all_and_a_sharp_one_is_the_antialiased_ring():
    """The walls' top edge out of focus (``plate.top_edge_blur_mm``): its outline spreads over the smear's width with
    the same total darkness; no wider than the line, the smear is the anti-aliased ring."""
    half_width, offsets = 0.09, np.linspace(-2.0, 2.0, 40001)
    step = offsets[1] - offsets[0]
    for width in (0.05, 0.3, 1.0):
        coverage = np.array([smeared_ring(10.0 + x, 10.0, half_width, width) for x in offsets])
        assert coverage.sum() * step == pytest.approx(2 * half_width, rel=1e-3)
        assert coverage.max() == pytest.approx(min(1.0, 2 * half_width / width), rel=1e-3)
        assert coverage[np.abs(offsets) > half_width + width / 2 + 1e-9].max() < 1e-12
    for x in (0.0, 0.05, 0.09, 0.1, 0.2):
        assert smeared_ring(10.0 + x, 10.0, half_width, 0.1) == pytest.approx(ring(10.0 + x, 10.0, half_width, 0.1))


def test_sharpening_the_luminance_leaves_no_coloured_halo():
    """A violet stain beside grey plastic: sharpening each channel overshoots the green most on the grey side (a
    teal line, as blind judges saw); sharpening the luminance alone adds the same detail to every channel."""
    image = np.empty((8, 40, 3), dtype=np.float32)
    image[:, :20] = (0.35, 0.05, 0.8)
    image[:, 20:] = (0.7, 0.7, 0.75)
    per_channel, on_luma = pp.sharpen(image, 1.5, 1.2), pp.sharpen(image, 1.5, 1.2, luma=1.0)
    grey_side = np.s_[:, 20:23]
    overshoot = (per_channel - image)[grey_side].mean(axis=(0, 1))
    assert overshoot[1] > 1.5 * overshoot[0] > 0.0 > overshoot[2]  # the green rises most: a teal halo (1.86 times)
    detail = on_luma - image
    np.testing.assert_allclose(detail[..., 0], detail[..., 1], atol=1e-6)
    np.testing.assert_allclose(detail[..., 2], detail[..., 1], atol=1e-6)
    np.testing.assert_allclose(pp._luminance(on_luma), pp._luminance(per_channel), atol=1e-6)  # as sharp to the eye
    half = pp.sharpen(image, 1.5, 1.2, luma=0.5)
    np.testing.assert_allclose(half, 0.5 * (per_channel + on_luma), atol=1e-6)


def test_sharpening_with_a_threshold_leaves_the_flat_stains_grain_alone():
    """``post.sharpen_threshold`` (coring): detail within the threshold of 0 is not sharpened, only what exceeds it,
    so a flat stain's grain of a level or two keeps its amplitude while an edge is sharpened nearly as much."""
    rng = np.random.default_rng(0)
    image = np.full((40, 80, 3), 0.3, dtype=np.float32)
    image[:, 40:] = 0.8  # an edge of 128 levels
    grain = (rng.standard_normal((40, 80, 1)) / 255.0).astype(np.float32)  # sd 1 level, the same in every channel
    grainy = image + grain
    plain, cored = pp.sharpen(grainy, 1.5, 1.0), pp.sharpen(grainy, 1.5, 1.0, threshold=3.0 / 255.0)
    flat = np.s_[:, 5:30]
    # unsharp masking amplifies the grain (by 1.5 times its share above the blur, here about 1.9 times); cored,
    # no pixel's grain detail exceeds 3 levels, so the flat side is left exactly as it was
    assert plain[flat].std() > 1.5 * grainy[flat].std()
    np.testing.assert_array_equal(cored[flat], grainy[flat])
    edge = np.s_[:, 38:43]
    overshoot_plain, overshoot_cored = (np.abs(out - grainy)[edge].max() for out in (plain, cored))
    assert overshoot_cored > 0.9 * overshoot_plain - 1.5 * 3.0 / 255.0  # the edge loses at most the threshold's share


def test_clean_isolated_pixels_hand_made_cases():
    mask = np.array(
        [
            [1, 1, 1, 0, 0],
            [1, 2, 1, 0, 0],
            [1, 1, 1, 0, 3],
            [0, 0, 0, 0, 0],
            [4, 4, 0, 5, 5],
        ],
        dtype=np.uint16,
    )
    cleaned = clean_isolated_pixels(mask)
    expected = mask.copy()
    expected[1, 1] = 1  # an isolated 2 inside 1s
    expected[2, 4] = 0  # an isolated 3 among background
    assert cleaned.dtype == np.uint16
    np.testing.assert_array_equal(cleaned, expected)
    # a tie among neighbours goes to the smaller value; a pixel with one equal neighbour is kept
    tie = np.array([[1, 1, 9], [2, 7, 1], [2, 2, 9]], dtype=np.uint8)
    assert clean_isolated_pixels(tie)[1, 1] == 1  # 1 and 2 have 3 votes each
    kept = np.array([[0, 0, 0], [0, 5, 5], [0, 0, 0]], dtype=np.uint8)
    np.testing.assert_array_equal(clean_isolated_pixels(kept), kept)
    with pytest.raises(ShapeMismatchError):
        clean_isolated_pixels(np.zeros((2, 2, 2)))


def test_post_processing_effects_change_the_image_as_described():
    rng = np.random.default_rng(0)
    image = np.clip(rng.normal(0.5, 0.1, (64, 80, 3)), 0, 1).astype(np.float32)
    assert pp.brightness(image, 0.2).mean() > image.mean() > pp.brightness(image, -0.2).mean()
    warm = pp.white_balance(image, (1.1, 1.0, 0.9))
    assert warm[..., 0].mean() > image[..., 0].mean() and warm[..., 2].mean() < image[..., 2].mean()
    assert pp.sharpen(image, 1.0).std() > image.std() > pp.gaussian_blur(image, 1.5).std()
    assert pp.clarity(image, 0.5).std() > image.std()
    stripes = np.zeros((40, 40, 3), dtype=np.float32)
    stripes[:, ::4] = 1.0
    blurred = pp.motion_blur(stripes, 4.0, 0.0)  # along the stripes' normal: smeared
    assert blurred[:, 8:32].std() < 0.5 * stripes[:, 8:32].std()
    assert np.allclose(pp.motion_blur(stripes, 4.0, 90.0)[8:32], stripes[8:32], atol=1e-5)  # along them: unchanged
    noisy = pp.sensor_noise(image, 5.0, np.random.default_rng(1))
    assert 2.0 / 255 < (noisy - image).std() < 8.0 / 255
    assert np.array_equal(noisy, pp.sensor_noise(image, 5.0, np.random.default_rng(1)))
    grainy = pp.sensor_noise(image, 5.0, np.random.default_rng(1), grain_px=1.0) - image  # clumped, its sd kept
    assert grainy.std() == pytest.approx((noisy - image).std(), rel=0.1)
    assert np.corrcoef(grainy[:, 1:].ravel(), grainy[:, :-1].ravel())[0, 1] > 0.6  # exp(-1/4) = 0.78 for blurred white noise
    shifted = pp.chromatic_aberration(image, 3.0)
    assert np.array_equal(shifted[..., 1], image[..., 1]) and not np.array_equal(shifted[..., 0], image[..., 0])
    dark = np.zeros((200, 200, 3), dtype=np.float32)
    dark[98:102, 98:102] = 1.0
    glowing = pp.bloom(dark, 0.5)
    assert glowing[100, 106].mean() > 0.01 and glowing[100, 130].mean() < glowing[100, 106].mean()
    assert pp.shadows(np.ones_like(image), 0.3, np.random.default_rng(2)).min() < 1.0
    levels = np.array([0.0, 0.02, 0.04, 0.52, 1.0], dtype=np.float32)
    # the black point 0.04: darker levels clip to 0 when stored, the rest stretched, white kept
    assert pp.to_uint8(pp.black_level(levels, 0.04)).tolist() == [0, 0, 0, 128, 255]
    u8 = pp.to_uint8(image)
    assert pp.jpeg_roundtrip(u8, 0.5).shape == u8.shape and not np.array_equal(pp.jpeg_roundtrip(u8, 0.5), u8)


def test_post_processing_switches_are_honoured():
    scene = small_scene("low", 2)
    plain = render(scene, SMALL).image
    noisy_post = scene.post.model_copy(update={"noise": scene.post.noise.model_copy(update={"enabled": True,
                                                                                             "strength": 6.0})})
    noisy = render(scene.model_copy(update={"post": noisy_post}), SMALL).image
    difference = noisy.astype(float) - plain.astype(float)
    assert 3.0 < difference.std() < 12.0


def test_plaque_counts_match_masks_for_sampled_scenes():
    scene = small_scene("high", 9, **{"plaques.negative_plate": 0.0})
    result = render(scene, SMALL)
    counts = plaque_counts(result.wells, result.plaques)
    visible = {w.id: 0 for w in scene.wells}
    for pid in np.unique(result.plaques)[1:]:
        visible[int(np.bincount(result.wells[result.plaques == pid]).argmax())] += 1
    assert {k: v for k, v in visible.items() if k in counts} == counts
    assert sum(counts.values()) == len(np.unique(result.plaques)) - 1


def test_each_plaque_belongs_to_the_well_holding_most_of_it_and_outside_wins_a_tie():
    wells = np.zeros((6, 12), np.uint8)
    wells[:, 2:6], wells[:, 6:10] = 1, 2
    plaques = np.zeros_like(wells, np.uint16)
    plaques[0, 4:9] = 1  # 2 pixels in well 1, 3 in well 2
    plaques[2, 0:4] = 2  # 2 outside, 2 in well 1: a tie, outside wins
    plaques[4, 8:12] = 3  # 2 in well 2, 2 outside: a tie again
    plaques[5, 3:6] = 4  # all in well 1
    assert plaque_wells(wells, plaques) == {1: 2, 2: 0, 3: 0, 4: 1}
    assert plaque_counts(wells, plaques) == {1: 1, 2: 1}
    assert plaque_counts(wells, plaques, [1, 2, 7]) == {1: 1, 2: 1, 7: 0}
    assert plaque_wells(wells, np.zeros_like(plaques)) == {}


def test_the_walls_top_edge_shows_through_the_floor_as_much_as_asked():
    """Seen from below, ``plate.top_edge_through_floor`` draws the walls' top edge as a dark arc across the
    monolayer and changes nothing else: not the masks, not a pixel away from the edge."""
    size = (640, 480)
    # no effect that spreads a change far: JPEG blocks, local contrast, bloom
    settings = {"plaques.negative_plate": 1.0, "camera.distance_mm": 180.0, "wells.emptied": 0.0,
                "post.jpeg": 0.0, "post.clarity": 0.0, "post.bloom": 0.0}
    hidden, shown = (small_scene("high", 6, **settings, **{"plate.top_edge_through_floor": share}) for share in (0.0, 1.0))
    assert hidden.camera.from_below and shown.plate_look.top_edge_through_floor == 1.0
    before, after = render(hidden, size), render(shown, size)
    assert np.array_equal(before.wells, after.wells)
    to_edge, on_floor, pixel_mm = distance_to_top_edges(shown, size)
    darker = before.image.astype(np.float64).mean(axis=2) - after.image.astype(np.float64).mean(axis=2)
    arc = on_floor & (to_edge < 0.5 * pixel_mm)
    away = to_edge > 6 * pixel_mm  # beyond the reach of the blur, sharpening and colour fringes
    assert arc.sum() > 500
    assert darker[arc].mean() > 3.0  # levels; the outline is thinner than a pixel here
    assert np.array_equal(before.image[away], after.image[away])
    off_floor = ~on_floor & (to_edge < 0.5 * pixel_mm) & (before.wells == 0)
    assert np.abs(darker[off_floor]).mean() < 0.5  # outside the floors the edge was drawn already


def test_the_floor_past_the_walls_top_edge_is_veiled_as_asked():
    """Seen from below, ``plate.crescent_veil`` mixes the monolayer's transmittance toward ``CRESCENT_LIGHT`` by that
    share where the floor lies past the walls' top edge (the light came through the wall): in linear light each
    pixel's change grows in proportion to the share, the stain's most absorbed channels rise, and it lies in a
    crescent on each well's side away from the camera's axis; an emptied well's floor there passes
    ``1 - share * (1 - CRESCENT_LIGHT)`` of its light; nothing else changes, not the masks."""
    size = (640, 480)
    settings = {"plaques.negative_plate": 1.0, "camera.distance_mm": 180.0, "wells.emptied": 0.0, "post.jpeg": 0.0,
                "post.clarity": 0.0, "post.bloom": 0.0, "post.noise": 0.0, "post.sharpen": 0.0,
                "plate.top_edge_through_floor": 0.0, "plate.top_edge_blur_mm": 0.0,
                "lighting.glare": 0.0}  # a glare adds light to both renders: the emptied floor's ratio rises toward 1
    scenes = [small_scene("high", 6, **settings, **{"plate.crescent_veil": share}) for share in (0.0, 0.05, 0.1)]
    plain, half, full = (render(scene, size) for scene in scenes)
    assert np.array_equal(plain.wells, full.wells) and np.array_equal(plain.plaques, full.plaques)
    past, pixel_mm = past_top_edge(scenes[2], size)
    crescent, opening = past > 2 * pixel_mm, past < -2 * pixel_mm
    assert crescent.sum() > 2000 and opening.sum() > 20000
    linear = [srgb_to_linear(result.image / 255.0) for result in (plain, half, full)]
    rise_half, rise_full = (np.mean(image[crescent] - linear[0][crescent], axis=0) for image in linear[1:])
    np.testing.assert_allclose(rise_full, 2.0 * rise_half, rtol=0.1, atol=5e-4)  # a mix: linear in the share
    relative = rise_full / linear[0][crescent].mean(axis=0)
    # a violet stain absorbs green most, then red: those rise (+4.2 and +0.16 of their light measured), blue barely
    assert relative[1] > relative[0] > 0.05 and abs(relative[2]) < 0.05, relative
    unchanged = ~ndimage.binary_dilation(~opening & ~np.isnan(past), iterations=4)  # beyond the floor's edge, defocus
    assert np.array_equal(plain.image[unchanged], full.image[unchanged])
    view = camera_view(scenes[2], *size)
    wells, _, _ = wells_in_view(scenes[2], view)
    u, v = pixel_centres_mm(view)
    for well in wells:
        mine = crescent & (np.hypot(u - well.center_mm[0], v - well.center_mm[1]) < scenes[2].plate.well_radius_mm)
        if mine.sum() < 50:  # too near the camera's axis for a crescent at this size
            continue
        direction = np.array([u[mine].mean() - well.center_mm[0], v[mine].mean() - well.center_mm[1]])
        assert direction @ (np.asarray(well.center_mm) - view.principal_mm) > 0, well.label
    emptied = [render(small_scene("high", 6, **(settings | {"wells.emptied": 1.0, "plate.crescent_veil": share})), size)
               for share in (0.0, 0.1)]
    lit = crescent & np.all(emptied[0].image < 250, axis=2)  # not clipped
    ratio = srgb_to_linear(emptied[1].image[lit] / 255.0) / srgb_to_linear(emptied[0].image[lit] / 255.0)
    np.testing.assert_allclose(np.median(ratio, axis=0), 1.0 - 0.1 * (1.0 - CRESCENT_LIGHT), atol=0.005)


def test_the_walls_refracted_lines_lie_where_asked():
    """``plate.wall_lines`` darkens thin lines across the band over each wall at ``WALL_LINE_PLACES`` of its width,
    each wandering around the well in two waves of ``WALL_LINE_WOBBLE_MM`` with its own phase
    (``look.wall_line_phase`` of the well's noise shifts), and ``plate.wall_highlights`` brightens the lines halfway
    between them; nothing else changes, not the masks."""
    size = (1216, 944)
    settings = {"plaques.negative_plate": 1.0, "wells.emptied": 0.0, "post.jpeg": 0.0, "post.clarity": 0.0,
                "post.bloom": 0.0, "post.noise": 0.0, "post.sharpen": 0.0, "camera.defocus_px": 0.0,
                "plate.top_edge_through_floor": 0.0, "plate.floor_height_mm": 0.0}
    plain, dark, bright = (small_scene("high", 6, **settings, **{"plate.wall_lines": a, "plate.wall_highlights": b})
                           for a, b in ((0.0, 0.0), (1.0, 0.0), (0.0, 0.4)))
    images = [render(scene, size) for scene in (plain, dark, bright)]
    assert all(np.array_equal(images[0].wells, result.wells) for result in images[1:])
    luminance = [result.image.astype(np.float64).mean(axis=2) for result in images]
    view = camera_view(plain, *size)
    wells, _, _ = wells_in_view(plain, view)
    offsets = scene_textures(plain).well_offsets
    u, v = pixel_centres_mm(view)
    radius, wall, pixel_mm = plain.plate.well_radius_mm, plain.plate.wall_mm, 1.0 / view.px_per_mm
    on_line, on_highlight = (np.zeros(u.shape, dtype=bool) for _ in range(2))
    for i, well in enumerate(wells):
        du, dv = u - well.center_mm[0], v - well.center_mm[1]
        t = np.arctan2(dv, du)
        for j, (place, highlight) in enumerate(zip(WALL_LINE_PLACES, WALL_HIGHLIGHT_PLACES, strict=True)):
            wobble = WALL_LINE_WOBBLE_MM * np.cos(2 * t - wall_line_phase(*offsets[i], j))
            off_centre = np.hypot(du, dv) - wobble
            on_line |= np.abs(off_centre - radius - place * wall) < 0.5 * pixel_mm
            on_highlight |= np.abs(off_centre - radius - highlight * wall) < 0.5 * pixel_mm
    near = wall_band(plain, size, margin_px=-4.0)
    darker, brighter = luminance[0] - luminance[1], luminance[2] - luminance[0]
    assert on_line.sum() > 3000 and on_highlight.sum() > 3000
    assert darker[on_line].mean() > 8.0  # levels on the lines
    assert darker[near & ~ndimage.binary_dilation(on_line, iterations=2)].mean() < 0.2 * darker[on_line].mean()
    assert brighter[on_highlight].mean() > 5.0
    assert brighter[near & ~ndimage.binary_dilation(on_highlight, iterations=2)].mean() < 0.2 * brighter[on_highlight].mean()
    for image in images[1:]:
        assert np.array_equal(images[0].image[~near], image.image[~near])


def test_the_band_over_the_walls_is_as_bright_as_asked():
    """``plate.wall_band`` brightens (or, negative, darkens) the plastic over each wall's thickness by that share
    and changes nothing else: not the masks, not a pixel away from the walls."""
    size = (640, 480)
    settings = {"plaques.negative_plate": 1.0, "wells.emptied": 0.0, "post.jpeg": 0.0, "post.clarity": 0.0,
                "post.bloom": 0.0, "post.noise": 0.0, "plate.top_edge_through_floor": 0.0}
    bright, dark = (small_scene("high", 6, **settings, **{"plate.wall_band": share}) for share in (0.04, -0.15))
    assert dark.plate_look.wall_band == -0.15 and bright.model_copy(
        update={"plate_look": bright.plate_look.model_copy(update={"wall_band": -0.15})}) == dark
    before, after = render(bright, size), render(dark, size)
    assert np.array_equal(before.wells, after.wells)
    band = wall_band(dark, size)
    assert band.sum() > 500
    ratio = after.image[band].astype(np.float64).mean() / before.image[band].astype(np.float64).mean()
    assert 0.90 < ratio < 0.925  # (1 - 0.15) / 1.04 = 0.817 in linear light, 0.91 display-encoded; 0.913 measured
    wide = ~wall_band(dark, size, margin_px=-6.0)  # beyond the reach of the blur and the sharpening
    assert np.array_equal(before.image[wide], after.image[wide])


def test_the_walls_foot_below_the_floor_shifts_the_band_outward():
    """``plate.floor_height_mm`` lifts the floors above the walls' foot: seen from below, the foot is nearer the
    camera, so its band and outlines are magnified by ``d / (d - h)`` about the camera's axis and shift away from it,
    and where the foot's opening shows no floor the band's brightness takes its place. The masks do not change (the
    plastic is clear), nor any pixel far from the walls."""
    size = (640, 480)
    settings = {"plaques.negative_plate": 1.0, "camera.distance_mm": 180.0, "wells.emptied": 0.0, "post.jpeg": 0.0,
                "post.clarity": 0.0, "post.bloom": 0.0, "post.noise": 0.0, "plate.top_edge_through_floor": 0.0,
                "plate.wall_band": 0.3, "plate.wall_slant": 0.0, "plate.wall_glints": 0.0}
    flat, lifted = (small_scene("high", 6, **settings, **{"plate.floor_height_mm": h}) for h in (0.0, 5.0))
    before, after = render(flat, size), render(lifted, size)
    assert np.array_equal(before.wells, after.wells) and np.array_equal(before.plaques, after.plaques)
    view = camera_view(lifted, *size)
    wells, _, _ = wells_in_view(lifted, view)
    centres = np.array([w.center_mm for w in wells])
    feet, scale = parallax(lifted, view, -5.0, centres)
    assert scale == pytest.approx(180.0 / (180.0 - 5.0))
    radius, wall = lifted.plate.well_radius_mm, lifted.plate.wall_mm
    u, v = pixel_centres_mm(view)
    margin = 1.5 / view.px_per_mm  # beyond the outlines and the blur
    was_band, is_band, was_near, is_near, near = (np.zeros(u.shape, dtype=bool) for _ in range(5))
    for (cx, cy), (fx, fy) in zip(centres, feet, strict=True):
        to_floor = np.hypot(u - cx, v - cy)
        to_foot = np.hypot(u - fx, v - fy)
        was_band |= (to_floor > radius + margin) & (to_floor < radius + wall - margin)
        was_near |= to_floor < radius + wall + margin
        is_band |= (to_foot < (radius + wall) * scale - margin) & (to_floor > radius + margin)
        is_near |= to_foot < (radius + wall) * scale + margin
        near |= to_floor < radius + wall + 3.0  # the shift, the outlines, the blur and the sharpening
    brighter = after.image.astype(np.float64).mean(axis=2) - before.image.astype(np.float64).mean(axis=2)
    gained, lost = is_band & ~was_near, was_band & ~is_near
    assert gained.sum() > 300 and lost.sum() > 100
    assert brighter[gained].mean() > 15.0  # levels: the band is 30 % brighter in linear light
    assert brighter[lost].mean() < -15.0
    assert np.array_equal(before.image[~near], after.image[~near])


def test_the_band_over_each_wall_takes_its_wells_stain_as_asked():
    """``plate.wall_stain`` tints the band over each wall by its well's layer: the light there is multiplied by the
    layer's transmittance at the well's density raised to that share, channel by channel (in linear light), and
    nothing else changes."""
    size = (640, 480)
    settings = {"plaques.negative_plate": 1.0, "wells.emptied": 0.0, "post.jpeg": 0.0, "post.clarity": 0.0,
                "post.bloom": 0.0, "post.noise": 0.0, "post.sharpen": 0.0, "plate.top_edge_through_floor": 0.0}
    plain, tinted = (small_scene("high", 6, **settings, **{"plate.wall_stain": share}) for share in (0.0, 0.05))
    before, after = render(plain, size), render(tinted, size)
    assert np.array_equal(before.wells, after.wells)
    view = camera_view(tinted, *size)
    wells, _, _ = wells_in_view(tinted, view)
    tints = wall_tints(tinted, wells, stain_table(tinted, scene_textures(tinted))[0])
    assert np.all(tints < 1.0) and tints[:, 1].max() < 0.85 and tints[:, 2].min() > 0.95  # a violet stain
    u, v = pixel_centres_mm(view)
    radius, wall = tinted.plate.well_radius_mm, tinted.plate.wall_mm
    margin = 1.5 / view.px_per_mm
    for well, tint in zip(wells, tints, strict=True):
        off_centre = np.hypot(u - well.center_mm[0], v - well.center_mm[1])
        band = (off_centre > radius + margin) & (off_centre < radius + wall - margin)
        ratio = srgb_to_linear(after.image[band] / 255.0).mean(axis=0) / srgb_to_linear(before.image[band] / 255.0).mean(axis=0)
        np.testing.assert_allclose(ratio, tint, atol=0.01)
    away = ~wall_band(tinted, size, margin_px=-6.0)
    assert np.array_equal(before.image[away], after.image[away])


def test_the_band_over_each_wall_changes_around_the_well_as_asked():
    """``plate.wall_slant`` and ``plate.wall_glints`` change the band's light around each well by the Fourier series
    of :func:`wall_sheen` (in linear light, pixel by pixel): brighter on the side away from the camera's axis, by
    ``wall_slant`` at most, and unevenly by the glints; nothing else changes."""
    size = (640, 480)
    settings = {"plaques.negative_plate": 1.0, "wells.emptied": 0.0, "post.jpeg": 0.0, "post.clarity": 0.0,
                "post.bloom": 0.0, "post.noise": 0.0, "post.sharpen": 0.0, "plate.top_edge_through_floor": 0.0,
                "plate.wall_band": 0.0, "plate.floor_height_mm": 0.0}
    plain, sheened = (small_scene("high", 6, **settings, **{"plate.wall_slant": slant, "plate.wall_glints": glints})
                      for slant, glints in ((0.0, 0.0), (0.2, 0.1)))
    before, after = render(plain, size), render(sheened, size)
    assert np.array_equal(before.wells, after.wells)
    view = camera_view(sheened, *size)
    wells, _, _ = wells_in_view(sheened, view)
    sheens = wall_sheen(sheened, wells, view.principal_mm, scene_textures(sheened).wall_glints)
    u, v = pixel_centres_mm(view)
    radius, wall = sheened.plate.well_radius_mm, sheened.plate.wall_mm
    margin = 1.5 / view.px_per_mm
    for well, (a1, b1, a2, b2, a3, b3) in zip(wells, sheens, strict=True):
        du, dv = u - well.center_mm[0], v - well.center_mm[1]
        off_centre = np.hypot(du, dv)
        band = (off_centre > radius + margin) & (off_centre < radius + wall - margin)
        t = np.arctan2(dv[band], du[band])
        expected = 1.0 + sum(a * np.cos(k * t) + b * np.sin(k * t)
                             for k, (a, b) in enumerate(((a1, b1), (a2, b2), (a3, b3)), start=1))
        ratio = (srgb_to_linear(after.image[band] / 255.0) / srgb_to_linear(before.image[band] / 255.0)).mean(axis=1)
        assert np.median(np.abs(ratio - expected)) < 0.01, well.label
        outward = (du[band] * (well.center_mm[0] - view.principal_mm[0])
                   + dv[band] * (well.center_mm[1] - view.principal_mm[1]))
        assert ratio[outward > 0].mean() > ratio[outward < 0].mean() + 0.1, well.label  # 0.2 * 4 / pi less glints
    away = ~wall_band(sheened, size, margin_px=-6.0)
    assert np.array_equal(before.image[away], after.image[away])


def test_the_walls_glints_are_as_uneven_as_asked_and_belong_to_their_wells():
    """Around each well the glints' change has the sd ``plate.wall_glints`` (over many wells), and each well keeps
    its own whatever the order the wells are passed in; ``plate.wall_slant`` adds that much along the direction
    from the camera's axis to the well."""
    scene = small_scene("high", 3, **{"plate.format": 96, "plate.wall_glints": 0.1, "plate.wall_slant": 0.0})
    glints = scene_textures(scene).wall_glints
    wells = list(scene.wells)
    sheens = wall_sheen(scene, wells, (60.0, 40.0), glints)
    sd_around = np.sqrt((sheens**2).sum(axis=1) / 2.0)  # each well's sd over its angle
    assert np.sqrt((sd_around**2).mean()) == pytest.approx(0.1, rel=0.1)
    np.testing.assert_array_equal(wall_sheen(scene, wells[::-1], (60.0, 40.0), glints), sheens[::-1])
    slanted = scene.model_copy(update={"plate_look": scene.plate_look.model_copy(update={"wall_slant": 0.2})})
    axis = (60.0, 40.0)
    added = wall_sheen(slanted, wells, axis, glints) - sheens
    outward = np.array([w.center_mm for w in wells]) - axis
    np.testing.assert_allclose(added[:, :2], 0.2 * outward / np.hypot(*outward.T)[:, None], atol=1e-12)
    assert not added[:, 2:].any()


def test_well_labels_sit_where_four_wells_meet_with_a_rib_to_their_well():
    """``plate.labels_at_junction`` puts each label circle (radius 0.11 pitch) on the junction of four wells, with a
    rib from the circle to its well's wall along the diagonal; else the circle lies 0.08 and 0.05 pitch nearer its
    well and there is no rib."""
    scene = small_scene("high", 2, **{"plate.format": 12, "plate.labels_at_junction": 1.0})
    elsewhere = small_scene("high", 2, **{"plate.format": 12, "plate.labels_at_junction": 0.0})
    assert scene.plate_look.labels_at_junction and not elsewhere.plate_look.labels_at_junction
    assert elsewhere.model_copy(update={"plate_look": scene.plate_look}) == scene  # its own stream: nothing else moves
    plate, k = scene.plate, 8.0
    pitch = plate.pitch_mm
    x, y = plate.a1_x_mm + 1.5 * pitch, plate.a1_y_mm + 0.5 * pitch  # where wells A2, A3, B2 and B3 meet: B3's label

    def ink(relief: np.ndarray, u: float, v: float) -> float:
        """The relief's largest magnitude within a texel of the plate point (u, v)."""
        row, col = int(v * k), int(u * k)
        return float(np.abs(relief[row - 1: row + 2, col - 1: col + 2]).max())

    at_junction, near_well = plate_relief(plate, k, True), plate_relief(plate, k, False)
    reach = 0.11 * pitch
    for relief, (cx, cy) in ((at_junction, (x, y)), (near_well, (x + 0.08 * pitch, y + 0.05 * pitch))):
        assert min(ink(relief, cx + dx, cy + dy) for dx, dy in ((reach, 0), (-reach, 0), (0, reach), (0, -reach))) > 0.2
    rib = 0.5 * (0.11 * pitch / np.sqrt(2.0) + 0.5 * pitch - (plate.well_radius_mm + plate.wall_mm) / np.sqrt(2.0))
    assert ink(at_junction, x + rib, y + rib) > 0.2 and ink(near_well, x + rib, y + rib) == 0.0


@pytest.mark.parametrize(("angle", "darker"), [(90.0, "bottom"), (270.0, "top"), (0.0, "left"), (180.0, "right")])
def test_the_side_a_plate_was_tilted_to_faces_the_image_as_documented(angle, darker):
    """``stain.rim_mottle_angle_deg`` as the catalogue describes it for a plate seen from below: 0 the image's left,
    90 its bottom. With the dye pooled there (``stain.pooling``), every well's red is lower on that side than on
    the opposite one."""
    overrides = {"stain.pooling": 1.0, "stain.rim_mottle_angle_deg": angle, "camera.from_below": 1.0,
                 "camera.rotation_deg": 0.0, "camera.tilt_deg": 0.0, "wells.emptied": 0.0,
                 "plaques.negative_plate": 1.0}
    scene = small_scene("high", 5, **overrides)
    result = render(scene, (512, 384))
    red = result.image[..., 0].astype(float)
    opposite = {"bottom": "top", "top": "bottom", "left": "right", "right": "left"}
    for well in scene.wells:
        rows, cols = np.nonzero(ndimage.binary_erosion(result.wells == well.id, iterations=2))
        dy, dx = rows - rows.mean(), cols - cols.mean()
        reach = 0.6 * (rows.max() - rows.min()) / 2
        side = {"bottom": dy > reach, "top": dy < -reach, "right": dx > reach, "left": dx < -reach}
        assert red[rows[side[darker]], cols[side[darker]]].mean() < red[rows[side[opposite[darker]]],
                                                                        cols[side[opposite[darker]]]].mean() - 3


def test_scratch_map_lies_where_the_image_shows_the_scrapes():
    scene = small_scene("high", 5, **{"artifacts.pipette_scratch": 1.0, "plaques.negative_plate": 1.0})
    size = (512, 384)
    result = render_raster(scene, size)
    scraped = scratch_map(scene, size)
    assert scraped.shape == (384, 512) and scraped.dtype == np.float32 and scraped.max() <= 1.0
    brightness = result.image.astype(float).sum(axis=2)
    for well in np.unique(result.wells)[1:]:
        inside = result.wells == well
        on = inside & (scraped > 0.5)
        assert on.sum() >= 3  # a scrape in every well
        # the layer where the map says it is scraped off is paler than the well's layer elsewhere
        assert np.median(brightness[on]) > np.median(brightness[inside & (scraped == 0)]) + 30
    clean = small_scene("high", 5, **{"artifacts.pipette_scratch": 0.0, "artifacts.extra_scratches": 0.0,
                                      "artifacts.rim_tears": 0.0})
    assert not clean.artifacts.scratches and not scratch_map(clean, size).any()


def test_smears_darken_the_layer_where_they_lie():
    overrides = {"artifacts.smears": 1.0, "artifacts.debris": 0.0, "plaques.negative_plate": 1.0}
    scene = small_scene("high", 4, **overrides)
    assert scene.artifacts.smears
    size = (512, 384)
    result = render_raster(scene, size)
    view = camera_view(scene, *size)
    wells, tops, top_radius = wells_in_view(scene, view)
    specks = draw_well_content(scene, view, wells, tops, top_radius, scene_textures(scene)).specks
    plain = render_raster(small_scene("high", 4, **(overrides | {"artifacts.smears": 0.0})), size).image
    brightness, before = result.image.astype(float).sum(axis=2), plain.astype(float).sum(axis=2)
    under = (specks > 0.3) & (result.wells > 0)
    assert under.sum() > 50
    assert np.median(before[under] - brightness[under]) > 40  # darker where a smear lies...
    # ...and nowhere else, past the reach of the blur, the chromatic aberration, the sharpening and the JPEG blocks
    away = ~ndimage.binary_dilation(specks > 0, iterations=32)
    assert away.mean() > 0.5
    np.testing.assert_array_equal(result.image[away], plain[away])
