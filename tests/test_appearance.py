"""The appearance model: the well content both renderers draw, and the plaque look's parameters."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from platesynth.render import appearance
from platesynth.render.sampling import grid_sample
from platesynth.render.textures import FOAM_HOLE_TEXELS, FOAM_TILE, foam_tile, scene_textures
from platesynth.scene import Plaque, PlaqueLook, load_config, sample_scene
from platesynth.scene.concrete import Artifacts, Scratch

TEXELS_PER_MM = 20.0


@pytest.fixture(scope="module")
def base_scene():
    scene = sample_scene(load_config("high", overrides={"plaques.negative_plate": 1.0}), 4)
    well = scene.wells[5]
    plaque = Plaque(id=1, well=well.id, center_mm=well.center_mm, radius_mm=1.0, fourier=(), softness=0.2, clearness=1.0)
    return scene.model_copy(update={"plaques": (plaque,)}), well


def well_content(scene, top_radius: float = 99.0) -> appearance.WellContent:
    """The appearance model's well content of ``scene`` on its texel grid (``top_radius`` in mm: the walls' top
    edge; the default clips nothing)."""
    grid = appearance.texel_grid(scene, TEXELS_PER_MM)
    wells = appearance.wells_by_grid(scene)
    centres = np.array([w.center_mm for w in wells])
    return appearance.draw_well_content(scene, grid, wells, centres, top_radius, scene_textures(scene))


def one_lysed_well(scene, well):
    """``scene`` without plaques, ``well`` its only lysed well."""
    return scene.model_copy(update={
        "plaques": (), "wells": tuple(w.model_copy(update={"lysed": w.id == well.id}) for w in scene.wells)})


def clearing_profile(scene, well, look: PlaqueLook) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Clearing and rim density along a ray from the plaque's centre (distance in mm)."""
    scene = scene.model_copy(update={"plaque_look": look})
    content = well_content(scene, scene.plate.well_radius_mm)
    row = int(well.center_mm[1] * TEXELS_PER_MM)
    columns = np.arange(int(well.center_mm[0] * TEXELS_PER_MM), int((well.center_mm[0] + 3.0) * TEXELS_PER_MM))
    distance = (columns + 0.5) / TEXELS_PER_MM - well.center_mm[0]
    return distance, content.clearing[row, columns], content.rim[row, columns]


def test_defaults_are_the_first_models_look(base_scene):
    scene, well = base_scene
    distance, clearing, rim = clearing_profile(scene, well, PlaqueLook())
    assert clearing[distance < 0.5].min() > 0.95  # a nearly fully cleared core (2 % dip at the centre)
    assert clearing[distance > 1.4].max() == 0.0  # nothing beyond the edge's ramp
    assert not rim.any()


def test_halo_clears_beyond_the_edge(base_scene):
    scene, well = base_scene
    distance, clearing, _ = clearing_profile(scene, well, PlaqueLook(fray=0.0, halo=0.3, halo_width=0.5))
    outside = (distance > 1.5) & (distance < 1.6)
    # the halo's clearing at ~0.55 mm beyond the outline: 0.3 * exp(-0.55 / 0.5) = 0.10
    assert clearing[outside].mean() == pytest.approx(0.3 * np.exp(-0.55 / 0.5), abs=0.02)


def test_edge_floor_widens_a_small_plaques_edge_only(base_scene):
    """``plaque_look.edge_floor_mm``: a plaque's edge ramp is the wider of softness times its radius and this floor,
    so a small plaque's edge widens to it and a large one's, already wider, stays; the outline (and the plaque
    masks) stay where they were."""
    scene, well = base_scene
    look = PlaqueLook(fray=0.0, centre_residual=0.0)

    def ramp_width(radius_mm: float, floor_mm: float) -> float:
        plaque = scene.plaques[0].model_copy(update={"radius_mm": radius_mm})
        resized = scene.model_copy(update={"plaques": (plaque,)})
        distance, clearing, _ = clearing_profile(resized, well, look.model_copy(update={"edge_floor_mm": floor_mm}))
        partly = (clearing > 0.1) & (clearing < 0.9)
        return float(np.ptp(distance[partly]))

    # radius 0.3 mm, softness 0.2: a 0.06 mm edge, about a texel; a floor of 0.3 mm widens it several-fold
    assert ramp_width(0.3, 0.0) < 0.15
    assert ramp_width(0.3, 0.3) > 3 * ramp_width(0.3, 0.0)
    # radius 2 mm: its 0.4 mm edge is wider than the floor, which changes nothing
    assert ramp_width(2.0, 0.3) == ramp_width(2.0, 0.0)
    wells = appearance.wells_by_grid(scene)
    table, _ = appearance.plaque_table(
        scene.model_copy(update={"plaque_look": look.model_copy(update={"edge_floor_mm": 0.3})}),
        wells, np.array([w.center_mm for w in wells]))
    assert table["edge_width"][0] == pytest.approx(0.3) and table["radius"][0] == 1.0


def test_centre_residual_makes_a_paler_centre(base_scene):
    scene, well = base_scene
    distance, clearing, _ = clearing_profile(scene, well, PlaqueLook(fray=0.0, centre_residual=0.4))
    assert clearing[0] == pytest.approx(0.6, abs=0.01)  # 1 - 0.4 at the centre
    assert clearing[(distance > 0.7) & (distance < 0.8)].mean() > 0.8


def test_edge_grain_keeps_clumps_of_stain_in_a_ring_inside_the_outline(base_scene):
    """``plaque_look.edge_grain``: in a ring inside a plaque's outline (``edge_grain_width`` of its radius deep),
    separate clumps of cells keep up to this share of the clearing; the middle stays cleared, the clearing beyond
    the outline does not grow, and the plaque masks do not change."""
    scene, well = base_scene
    col, row = (int(c * TEXELS_PER_MM) for c in well.center_mm)
    reach = int(1.2 * TEXELS_PER_MM)
    yy, xx = np.mgrid[-reach:reach, -reach:reach]
    # from the plaque's centre (texel centres lie at (i + 0.5) / TEXELS_PER_MM); its radius is 1 mm, its edge 0.2 mm
    radius_mm = np.hypot((row + yy + 0.5) / TEXELS_PER_MM - well.center_mm[1],
                         (col + xx + 0.5) / TEXELS_PER_MM - well.center_mm[0])
    window = (slice(row - reach, row + reach), slice(col - reach, col + reach))
    look = PlaqueLook(fray=0.0, centre_residual=0.0)
    even = well_content(scene.model_copy(update={"plaque_look": look}))
    grainy = well_content(scene.model_copy(update={"plaque_look": look.model_copy(
        update={"edge_grain": 0.8, "edge_grain_width": 0.2})}))
    even_clear, grainy_clear = even.clearing[window], grainy.clearing[window]
    np.testing.assert_array_equal(grainy.plaque_ids, even.plaque_ids)
    assert np.all(grainy_clear <= even_clear + 1e-6)
    ring = (radius_mm > 0.8) & (radius_mm < 0.9)
    middle = radius_mm < 0.3
    kept = 1.0 - grainy_clear[ring] / even_clear[ring]  # the share of the clearing the clumps keep
    # clumps, not a darker band: about a quarter of the ring (the fine tile beyond GRAIN_LEVEL sd) keeps a share,
    # at most 0.8 * exp(-(1 - r) / 0.2) at r of the radius (0.36-0.49 here), and the rest is cleared as before
    most = 0.8 * np.exp(-(1.0 - radius_mm[ring]) / 0.2)
    assert 0.1 < (kept > 0.05).mean() < 0.5
    assert np.all(kept <= most + 1e-3) and (kept / most).max() > 0.95
    assert np.median(kept) < 0.02
    # the middle, 0.7-1 of the radius from the ring, keeps at most 0.8 * exp(-0.7 / 0.2) = 0.024
    assert (1.0 - grainy_clear[middle] / even_clear[middle]).max() < 0.025


def test_residual_mottle_leaves_patches_of_stain_inside_a_plaque(base_scene):
    """``plaque_look.residual_mottle``: the share of stain left in a cleared plaque varies in patches around its mean
    (0.03), by this sd, clipped at 0; the stain around the plaque stays as it was."""
    scene, well = base_scene
    col, row = (int(c * TEXELS_PER_MM) for c in well.center_mm)
    reach = int(0.4 * TEXELS_PER_MM)  # the plaque's core: 0.4 of its radius, clear of its soft edge
    yy, xx = np.mgrid[-reach:reach, -reach:reach]
    inside = np.hypot(yy, xx) < reach
    core = (row + yy[inside], col + xx[inside])
    beside = (row, col + int(5 * TEXELS_PER_MM))

    def green_absorbance(mottle: float) -> tuple[np.ndarray, float]:
        look = PlaqueLook(fray=0.0, residual_mottle=mottle)
        floor = appearance.floor_transmittance(scene.model_copy(update={"plaque_look": look}), TEXELS_PER_MM)
        absorbance = -np.log(floor[..., 1])
        return absorbance[core] / absorbance[beside], float(floor[beside][1])

    even, outside_even = green_absorbance(0.03)
    patchy, outside_patchy = green_absorbance(0.2)
    assert outside_patchy == outside_even
    # the core's absorbance, relative to the stain beside the plaque: nearly even with the default (0.02-0.18, sd
    # 0.04); with 0.2 in patches from nearly clear to three quarters of the stain's
    assert even.max() < 0.2 and even.std() < 0.05
    assert patchy.max() > 0.6 and patchy.std() > 4 * even.std()
    assert patchy.mean() > even.mean() + 0.15  # the share left is clipped at 0: more patchy is more stain on average


def test_residual_tint_gives_the_stain_left_in_a_plaque_the_lysed_colour(base_scene):
    """``plaque_look.residual_tint`` 1: the stain left at a half-cleared plaque's centre has the colour of what a
    lysed well keeps (the ratios of its absorbances across channels); 0: the layer's own colour."""
    scene, well = base_scene
    pale = {"lysed_paleness": 1.0, "lysed_hue_deg": 230.0, "lysed_saturation": 0.4}
    scene = scene.model_copy(update={
        "stain": scene.stain.model_copy(update=pale),
        "plaques": (scene.plaques[0].model_copy(update={"clearness": 0.5}),)})
    table = appearance.stain_table(scene, scene_textures(scene))[0]
    col, row = (int(c * TEXELS_PER_MM) for c in well.center_mm)

    def absorbance_ratios(tint: float) -> np.ndarray:
        look = PlaqueLook(fray=0.0, centre_residual=0.0, residual_tint=tint)
        floor = appearance.floor_transmittance(scene.model_copy(update={"plaque_look": look}), TEXELS_PER_MM)
        t = table["translucency"]
        absorbance = -np.log((floor[row, col] - t) / (1.0 - t))
        return absorbance / absorbance[1]

    layer = np.array([table["absorbance_r"], table["absorbance_g"], table["absorbance_b"]])
    lysed = np.array([table["lysed_absorbance_r"], table["lysed_absorbance_g"], table["lysed_absorbance_b"]])
    assert not np.allclose(layer / layer[1], lysed / lysed[1], atol=0.05)
    np.testing.assert_allclose(absorbance_ratios(0.0), layer / layer[1], atol=1e-3)
    # half cleared: half of what is left takes the lysed colour, half keeps the layer's
    np.testing.assert_allclose(absorbance_ratios(1.0), (layer + lysed) / (layer + lysed)[1], atol=1e-3)


def test_rim_is_a_band_on_the_outline(base_scene):
    scene, well = base_scene
    distance, _, rim = clearing_profile(scene, well, PlaqueLook(fray=0.0, rim=0.5))
    assert rim.max() == pytest.approx(0.5, abs=0.01)
    assert abs(distance[np.argmax(rim)] - 1.0) < 0.06  # on the outline (radius 1 mm)
    assert rim[distance < 0.5].max() < 0.01


def test_fray_zero_gives_a_round_edge(base_scene):
    scene, well = base_scene
    scene = scene.model_copy(update={"plaque_look": PlaqueLook(fray=0.0)})
    clearing = well_content(scene).clearing
    ys, xs = np.nonzero(clearing > 0.5)
    radii = np.hypot((xs + 0.5) / TEXELS_PER_MM - well.center_mm[0], (ys + 0.5) / TEXELS_PER_MM - well.center_mm[1])
    assert radii.max() - 1.0 < 0.08  # the half-clearing contour is the outline, within about a texel


def outline_radii(scene, well, look: PlaqueLook) -> tuple[np.ndarray, np.ndarray]:
    """The plaque's outline (its mask's boundary) and its half-clearing contour: the largest radius (mm) of each in
    72 sectors around the centre."""
    scene = scene.model_copy(update={"plaque_look": look})
    content = well_content(scene)
    radii = []
    for region in (content.plaque_ids > 0, content.clearing > 0.5):
        ys, xs = np.nonzero(region)
        du, dv = (xs + 0.5) / TEXELS_PER_MM - well.center_mm[0], (ys + 0.5) / TEXELS_PER_MM - well.center_mm[1]
        sector = ((np.arctan2(dv, du) + np.pi) / (2 * np.pi) * 72).astype(int) % 72
        radii.append(np.array([np.hypot(du, dv)[sector == k].max() for k in range(72)]))
    return radii[0], radii[1]


def test_lumps_move_the_outline_and_its_mask_alike(base_scene):
    scene, well = base_scene
    mask, half = outline_radii(scene, well, PlaqueLook(fray=0.0))
    assert mask.std() < 0.02 and half.std() < 0.02  # a round plaque of radius 1 mm
    mask, half = outline_radii(scene, well, PlaqueLook(fray=0.0, lumps=0.1))
    # lumps of 0.12 mm cells move the outline by 0.1 mm per sd of the noise, out and in around the plaque
    assert 0.03 < mask.std() < 0.2 and mask.min() < 0.95 and mask.max() > 1.05
    assert mask.mean() == pytest.approx(1.0, abs=0.1)
    np.testing.assert_allclose(half, mask, atol=0.08)  # the mask is the clearing's outline, lumps and all
    # the outline does not depend on the edge's softness: a sharp plaque's drawn box reaches its outmost lumps (8 of
    # 72 sectors were clipped by up to 0.61 mm before the box counted the lumps)
    sharp = scene.model_copy(update={"plaques": (scene.plaques[0].model_copy(update={"softness": 0.02}),)})
    rough = PlaqueLook(fray=0.0, lumps=0.25)
    np.testing.assert_allclose(outline_radii(sharp, well, rough)[0], outline_radii(scene, well, rough)[0])


def test_floor_texture_is_the_raster_renderers_stain(base_scene):
    """Blender's floor texture: the plaque's core passes far more light than the stain beside it, outside the
    wells the texture is clear."""
    scene, well = base_scene
    floor = appearance.floor_transmittance(scene.model_copy(update={"plaque_look": PlaqueLook()}), TEXELS_PER_MM)
    row, col = (int(c * TEXELS_PER_MM) for c in well.center_mm[::-1])
    core, stained = floor[row, col], floor[row, col + int(5 * TEXELS_PER_MM)]
    assert core.mean() > stained.mean() + 0.3
    assert np.all(core >= stained)
    assert floor[0, 0].tolist() == [1.0, 1.0, 1.0]


def test_lysed_density_sets_how_pale_a_lysed_well_is(base_scene):
    scene, well = base_scene
    lysed = one_lysed_well(scene, well)
    row, col = (int(c * TEXELS_PER_MM) for c in well.center_mm[::-1])
    reach = int(4 * TEXELS_PER_MM)

    def mean_transmittance(**stain) -> float:
        variant = lysed.model_copy(update={"stain": lysed.stain.model_copy(update=stain)})
        floor = appearance.floor_transmittance(variant, TEXELS_PER_MM)
        return float(floor[row - reach: row + reach, col - reach: col + reach].mean())

    intact = float(appearance.floor_transmittance(scene.model_copy(update={"plaques": ()}), TEXELS_PER_MM)[
        row - reach: row + reach, col - reach: col + reach].mean())
    dense, pale = mean_transmittance(lysed_density=0.6), mean_transmittance(lysed_density=0.2)
    assert intact < dense < pale < 1.0
    # flakes: the grain spreads the remnant's transmittance without moving its mean much
    grainy = appearance.floor_transmittance(
        lysed.model_copy(update={"stain": lysed.stain.model_copy(update={"lysed_grain": 0.8})}), TEXELS_PER_MM)
    smooth = appearance.floor_transmittance(lysed, TEXELS_PER_MM)
    window = np.s_[row - reach: row + reach, col - reach: col + reach, 1]

    def fine_detail(floor: np.ndarray) -> float:  # what a 0.5 mm blur removes
        green = floor[window].astype(np.float64)
        return float((green - ndimage.gaussian_filter(green, 0.5 * TEXELS_PER_MM)).std())

    assert fine_detail(grainy) > 1.25 * fine_detail(smooth)  # 1.36 measured (strands and drying detail remain)


def test_a_lace_wells_layer_keeps_the_lysed_density_in_the_lysed_colour(base_scene):
    """Between a lace well's plaques the layer is damaged: at every texel it keeps ``stain.lysed_density`` of the
    intact layer's density, in the colour of what a lysed well keeps (no film: the same unevenness)."""
    scene, well = base_scene
    pale = {"lysed_paleness": 1.0, "lysed_hue_deg": 230.0, "lysed_saturation": 0.4, "lysed_density": 0.3}
    scene = scene.model_copy(update={"plaques": (), "stain": scene.stain.model_copy(update=pale)})
    laced = scene.model_copy(update={"wells": tuple(
        w.model_copy(update={"lysed": w.id == well.id, "lace": w.id == well.id}) for w in scene.wells)})
    table = appearance.stain_table(scene, scene_textures(scene))[0]
    t = table["translucency"]
    row, col = (int(c * TEXELS_PER_MM) for c in well.center_mm[::-1])
    window = np.s_[row - 40: row + 40, col - 40: col + 40]

    def absorbance(variant) -> np.ndarray:
        return -np.log((appearance.floor_transmittance(variant, TEXELS_PER_MM)[window] - t) / (1.0 - t))

    layer = np.array([table["absorbance_r"], table["absorbance_g"], table["absorbance_b"]])
    lysed = np.array([table["lysed_absorbance_r"], table["lysed_absorbance_g"], table["lysed_absorbance_b"]])
    np.testing.assert_allclose(absorbance(laced) / absorbance(scene), np.broadcast_to(0.3 * lysed / layer, (80, 80, 3)),
                               rtol=2e-3)


def _texel_places(shape: tuple[int, ...], well) -> tuple[np.ndarray, np.ndarray]:
    """Each floor texel's distance from ``well``'s centre (mm) and its direction (radians, plate x axis 0)."""
    rows, cols = np.indices(shape[:2])
    du = (cols + 0.5) / TEXELS_PER_MM - well.center_mm[0]
    dv = (rows + 0.5) / TEXELS_PER_MM - well.center_mm[1]
    return np.hypot(du, dv), np.arctan2(dv, du)


def test_lysed_disc_gathers_the_remnant_in_the_middle_of_the_well(base_scene):
    scene, well = base_scene
    lysed = one_lysed_well(scene, well)  # a thin film everywhere (lysed_residue), whatever the preset draws
    lysed = lysed.model_copy(update={"stain": lysed.stain.model_copy(update={"lysed_residue": 0.15})})
    radius = scene.plate.well_radius_mm

    def density(**stain) -> tuple[float, float]:
        """Mean -log green transmittance within 0.3 radii of the centre, and between 0.8 and 0.95."""
        variant = lysed.model_copy(update={"stain": lysed.stain.model_copy(update=stain)})
        green = -np.log(appearance.floor_transmittance(variant, TEXELS_PER_MM)[..., 1].astype(np.float64))
        distance, _ = _texel_places(green.shape, well)
        return (float(green[distance < 0.3 * radius].mean()),
                float(green[(distance > 0.8 * radius) & (distance < 0.95 * radius)].mean()))

    cloud_centre, cloud_rim = density(lysed_disc=0.0)
    disc_centre, disc_rim = density(lysed_disc=0.8, lysed_disc_radius=0.5)
    assert disc_centre > 2.5 * cloud_centre  # the remnant gathers in the disc (3.5 times, measured)...
    assert disc_rim < 0.4 * cloud_rim  # ...and thins out around it (0.22 times)
    wide_centre, wide_rim = density(lysed_disc=0.8, lysed_disc_radius=0.9)
    assert wide_rim > 5 * disc_rim  # a wider disc reaches toward the rim (13 times)


def test_lysed_rim_loss_clears_a_ring_at_the_rim_or_lets_the_film_reach_the_wall(base_scene):
    scene, well = base_scene
    lysed = one_lysed_well(scene, well)
    radius = scene.plate.well_radius_mm

    def density(rim_loss: float) -> tuple[float, float]:
        """Mean -log green transmittance within 0.3 mm of the rim, and between 0.5 and 0.6 radii."""
        variant = lysed.model_copy(update={"stain": lysed.stain.model_copy(update={"lysed_rim_loss": rim_loss})})
        green = -np.log(appearance.floor_transmittance(variant, TEXELS_PER_MM)[..., 1].astype(np.float64))
        distance, _ = _texel_places(green.shape, well)
        return (float(green[(distance > radius - 0.3) & (distance < radius)].mean()),
                float(green[(distance > 0.5 * radius) & (distance < 0.6 * radius)].mean()))

    ring_rim, ring_inner = density(0.7)
    film_rim, film_inner = density(0.0)
    # the loss is 1 - rim_loss * exp(-(R - d) / 1.5 mm): about 1 - 0.7 * 0.91 = 0.37 of the film at the wall
    assert ring_rim / film_rim == pytest.approx(0.37, abs=0.05)
    assert ring_inner / film_inner == pytest.approx(1.0, abs=0.05)  # 4.4 mm or more inside, barely touched


def test_lysed_haze_dims_what_a_lysed_well_keeps_alike_in_every_channel_by_its_density(base_scene):
    """``stain.lysed_haze`` adds an absorbance the same in red, green and blue to what a lysed well keeps, per unit
    of its density: the transmittance of every channel falls by ``exp(-haze * density)``, where the green's own
    absorbance gives the density; a scene without a lysed well is untouched."""
    scene, well = base_scene
    lysed = one_lysed_well(scene, well)
    lysed = lysed.model_copy(update={"stain": lysed.stain.model_copy(update={"translucency": 0.0,
                                                                              "unevenness_light": 0.0})})
    hazed = lysed.model_copy(update={"stain": lysed.stain.model_copy(update={"lysed_haze": 1.5})})
    clear, grey = (appearance.floor_transmittance(s, TEXELS_PER_MM).astype(np.float64) for s in (lysed, hazed))
    distance, _ = _texel_places(clear.shape[:2], well)
    inside = distance < 0.9 * scene.plate.well_radius_mm
    green_absorbance = float(appearance.stain_table(lysed, scene_textures(lysed))["lysed_absorbance_g"][0])
    density = -np.log(clear[inside, 1]) / green_absorbance
    for channel in range(3):
        np.testing.assert_allclose(grey[inside, channel], clear[inside, channel] * np.exp(-1.5 * density), rtol=2e-3)
    assert float(grey[inside, 2].mean()) < 0.9 * float(clear[inside, 2].mean())  # a darker, greyer film
    unlysed_clear, unlysed_grey = (appearance.floor_transmittance(
        s.model_copy(update={"wells": scene.wells}), TEXELS_PER_MM) for s in (lysed, hazed))
    np.testing.assert_array_equal(unlysed_clear, unlysed_grey)  # no lysed well: the haze changes nothing


def test_lysed_clumps_keep_islands_of_intact_stain_on_about_their_share_of_the_well(base_scene):
    scene, well = base_scene
    lysed = one_lysed_well(scene, well)
    intact_floor = appearance.floor_transmittance(scene.model_copy(update={"plaques": ()}), TEXELS_PER_MM)
    inside = _texel_places(intact_floor.shape, well)[0] < 0.9 * scene.plate.well_radius_mm
    intact = -np.log(intact_floor[..., 1][inside].astype(np.float64))

    def green_density(clumps: float) -> np.ndarray:
        variant = lysed.model_copy(update={"stain": lysed.stain.model_copy(update={"lysed_clumps": clumps})})
        return -np.log(appearance.floor_transmittance(variant, TEXELS_PER_MM)[..., 1][inside].astype(np.float64))

    none, some = green_density(0.0), green_density(0.03)
    assert (none > 0.5 * intact).mean() < 0.002  # without clumps, nothing of the lysed well is near intact
    near_intact = (some > 0.5 * intact).mean()
    # 0.018 measured for 0.03: half of intact needs the noise half an edge above the level, which fewer texels reach
    assert 0.01 < near_intact < 0.03
    assert np.all(some >= none - 1e-5)  # clumps only add stain
    # the clumps are intact cells: the plate's colour, where the rest of the well keeps a pale, bluish one
    pale = {"lysed_paleness": 1.0, "lysed_hue_deg": 240.0, "lysed_saturation": 0.5, "lysed_clumps": 0.03}
    variant = lysed.model_copy(update={"stain": lysed.stain.model_copy(update=pale)})
    absorbance = -np.log(appearance.floor_transmittance(variant, TEXELS_PER_MM)[inside].astype(np.float64))
    intact_absorbance = -np.log(intact_floor[inside].astype(np.float64))
    core, film = some > 0.9 * intact, some <= none + 1e-9  # within clumps, and where none lies

    def red_over_blue(a: np.ndarray) -> float:
        return float(a[:, 0].sum() / a[:, 2].sum())

    assert red_over_blue(absorbance[core]) == pytest.approx(red_over_blue(intact_absorbance), rel=0.02)  # 0.005 measured
    assert red_over_blue(absorbance[film]) > 1.1 * red_over_blue(intact_absorbance)  # 1.20 times measured
    assert appearance.clump_level(0.0) == np.inf and appearance.clump_level(0.5) == pytest.approx(0.0)


def _blue_density_by_place(scene, well, **stain) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """-log blue floor transmittance (the channel a violet stain passes most) of ``scene`` with ``stain`` changed, and
    :func:`_texel_places`."""
    variant = scene.model_copy(update={"plaques": (), "stain": scene.stain.model_copy(update=stain)})
    blue = -np.log(appearance.floor_transmittance(variant, TEXELS_PER_MM)[..., 2].astype(np.float64))
    return blue, *_texel_places(blue.shape, well)


def test_meniscus_darkens_a_thin_line_along_the_rim(base_scene):
    scene, well = base_scene
    radius = scene.plate.well_radius_mm
    plain, distance, _ = _blue_density_by_place(scene, well, meniscus=0.0)
    lined, _, _ = _blue_density_by_place(scene, well, meniscus=2.0)
    edge = (distance > radius - 0.1) & (distance < radius)
    inner = distance < radius - appearance.RIM_REACH * appearance.MENISCUS_MM
    # 2.56 times measured; 1 + 2 * (0.2 / 0.1) * (1 - e^-0.5) = 2.57 expected over the outer 0.1 mm
    assert lined[edge].mean() == pytest.approx(2.57 * plain[edge].mean(), rel=0.03)
    assert np.array_equal(lined[inner], plain[inner])  # nothing changes further in


def test_a_one_sided_mottled_band_is_strongest_toward_its_direction(base_scene):
    scene, well = base_scene
    radius = scene.plate.well_radius_mm
    plain, distance, angle = _blue_density_by_place(scene, well, rim_mottle=0.0)
    band = (distance > radius - 1.0) & (distance < radius)

    def paling(direction_deg: float, side: float) -> tuple[float, float]:
        """How much paler the band is than without the mottle, on the side facing 0 deg and on the opposite side."""
        mottled, _, _ = _blue_density_by_place(scene, well, rim_mottle=0.6, rim_mottle_mm=1.0,
                                                rim_mottle_side=side, rim_mottle_angle_deg=direction_deg)
        facing = band & (np.cos(angle) > 0.9)
        opposite = band & (np.cos(angle) < -0.9)
        return tuple(float((1.0 - mottled[side] / plain[side]).mean()) for side in (facing, opposite))

    even_facing, even_opposite = paling(0.0, 0.0)
    assert even_facing == pytest.approx(even_opposite, rel=0.3)  # all around
    facing, opposite = paling(0.0, 1.0)
    assert facing == pytest.approx(even_facing, rel=0.1) and opposite < 0.05 * facing  # one side only
    turned_facing, turned_opposite = paling(180.0, 1.0)
    assert turned_opposite == pytest.approx(facing, rel=0.3) and turned_facing < 0.05 * facing


def test_a_patchy_mottled_band_comes_and_goes_along_the_rim(base_scene):
    """``stain.rim_mottle_patches`` 1 leaves stretches of the rim bare of the mottle (about half of it), where 0 pales
    every stretch; where the patches keep it, it is as pale as without them."""
    scene, well = base_scene
    radius = scene.plate.well_radius_mm
    plain, distance, angle = _blue_density_by_place(scene, well, rim_mottle=0.0)
    band = (distance > radius - 1.0) & (distance < radius)
    sectors = np.floor((angle + np.pi) / (2.0 * np.pi) * 36).astype(int) % 36  # 36 stretches of about 2 mm

    def paling(patches: float) -> np.ndarray:
        """How much paler the band is than without the mottle, in each of the 36 stretches."""
        mottled, _, _ = _blue_density_by_place(scene, well, rim_mottle=0.6, rim_mottle_mm=1.0,
                                                rim_mottle_patches=patches)
        loss = 1.0 - mottled[band] / plain[band]
        return np.array([loss[sectors[band] == k].mean() for k in range(36)])

    even, patchy = paling(0.0), paling(1.0)
    assert even.min() > 0.5 * even.mean()  # every stretch paled (0.13 at least, 0.19 on average, measured)
    bare = patchy < 0.2 * even.mean()
    assert 0.2 < bare.mean() < 0.8, bare.mean()  # 0.56 of the stretches measured
    assert np.all(patchy <= even + 1e-9) and patchy.max() > 0.8 * even.mean()


def test_the_mottled_bands_patches_grow_with_its_grain(base_scene):
    """``stain.rim_mottle_grain_mm`` is the cell of the patches' noise: three times the grain, patches three times as
    long (the lag at which the paling's autocorrelation along a row of the band falls to a half), as pale."""
    scene, well = base_scene
    plain, distance, _ = _blue_density_by_place(scene, well, rim_mottle=0.0)
    radius = scene.plate.well_radius_mm
    band = distance < radius - 0.5  # a band 30 mm wide: the whole well but its rim, evenly mottled

    def patches(grain_mm: float) -> tuple[float, float]:
        """The half-correlation length of the paling along the rows (mm) and its mean."""
        mottled, _, _ = _blue_density_by_place(scene, well, rim_mottle=0.5, rim_mottle_mm=30.0,
                                                rim_mottle_grain_mm=grain_mm)
        paling = np.full(plain.shape, np.nan)
        paling[band] = 1.0 - mottled[band] / plain[band]
        rows = [r[~np.isnan(r)] for r in paling if (~np.isnan(r)).sum() > 200]
        lags = np.arange(1, 60)
        correlation = [np.mean([np.corrcoef(r[:-lag], r[lag:])[0, 1] for r in rows]) for lag in lags]
        return float(lags[np.argmax(np.array(correlation) < 0.5)] / TEXELS_PER_MM), float(np.nanmean(paling))

    fine, coarse = patches(0.06), patches(0.18)
    assert coarse[0] == pytest.approx(3.0 * fine[0], rel=0.25)  # 0.15 and 0.40 mm measured (in 0.05 mm steps)
    assert coarse[1] == pytest.approx(fine[1], rel=0.2)  # 0.22 and 0.21


def test_lysed_paleness_moves_a_lysed_wells_remnant_to_the_pale_colour(base_scene):
    scene, well = base_scene
    other = next(w for w in scene.wells if w.id != well.id and not w.emptied)
    lysed = one_lysed_well(scene, well)
    reach = int(3 * TEXELS_PER_MM)

    def window(floor: np.ndarray, w) -> np.ndarray:
        row, col = (int(c * TEXELS_PER_MM) for c in w.center_mm[::-1])
        return floor[row - reach: row + reach, col - reach: col + reach].reshape(-1, 3).astype(np.float64)

    def absorbance_ratios(floor: np.ndarray, w) -> np.ndarray:  # red and blue absorbance over green's
        absorbance = -np.log(window(floor, w)).mean(axis=0)
        return absorbance[[0, 2]] / absorbance[1]

    pale = {"lysed_paleness": 1.0, "lysed_hue_deg": 240.0, "lysed_saturation": 0.5}
    plate_colour = appearance.floor_transmittance(lysed, TEXELS_PER_MM)
    pale_colour = appearance.floor_transmittance(
        lysed.model_copy(update={"stain": lysed.stain.model_copy(update=pale)}), TEXELS_PER_MM)
    # the remnant takes the colour of hue 240 deg, saturation 0.5: red absorbs as much as green, more than blue
    pale_stain = lysed.stain.model_copy(update={"hue_deg": 240.0, "saturation": 0.5})
    expected = appearance.stain_absorbance(pale_stain)
    np.testing.assert_allclose(absorbance_ratios(pale_colour, well), expected[[0, 2]] / expected[1], atol=0.02)
    assert not np.allclose(absorbance_ratios(plate_colour, well), expected[[0, 2]] / expected[1], atol=0.1)
    # intact wells keep the plate's colour
    assert window(pale_colour, other).tolist() == window(plate_colour, other).tolist()


def test_the_raster_renderer_draws_the_pale_lysed_colour(base_scene):
    from platesynth.render.raster import render_raster

    scene, well = base_scene
    lysed = one_lysed_well(scene, well)
    pale = lysed.model_copy(update={"stain": lysed.stain.model_copy(
        update={"lysed_paleness": 1.0, "lysed_hue_deg": 240.0, "lysed_saturation": 0.5})})
    usual, paler = render_raster(lysed, (480, 360)), render_raster(pale, (480, 360))
    inside = usual.wells == well.id

    def absorbed_red_over_green(image: np.ndarray) -> float:  # hue 240: red absorbed at least as much as green
        absorbed = 255.0 - image[inside].astype(np.float64).mean(axis=0)
        return float(absorbed[0] / absorbed[1])

    assert absorbed_red_over_green(paler.image) > absorbed_red_over_green(usual.image) + 0.1  # 1.14 -> 1.34 measured
    others = (usual.wells > 0) & ~inside  # the intact wells as they were (but for the post-processing's spread)
    np.testing.assert_allclose(usual.image[others].mean(axis=0), paler.image[others].mean(axis=0), atol=0.01)


def one_scratch(scene, **artifacts):
    """``scene`` with one straight scratch 4 mm long and 0.6 mm wide down the middle of its sixth well (and no
    plaques), the scratches' other settings ``artifacts``; and that well."""
    well = scene.wells[5]
    x, y = well.center_mm
    scratch = Scratch(well=well.id, points_mm=((x, y - 2.0), (x, y), (x, y + 2.0)), width_mm=0.6)
    return scene.model_copy(update={"artifacts": Artifacts(scratches=(scratch,), **artifacts), "plaques": ()}), well


def scratch_widths(scene, roughness: float) -> tuple[np.ndarray, np.ndarray]:
    """Widths (mm) of the scraped band of one straight 4 mm scratch on either side of its centre line, along it in
    0.05 mm steps."""
    scene, well = one_scratch(scene, scratch_roughness=roughness)
    x, y = well.center_mm
    scraped = well_content(scene).scratched
    rows = np.arange(int((y - 1.6) * TEXELS_PER_MM), int((y + 1.6) * TEXELS_PER_MM))
    band = scraped[rows] / scene.artifacts.scratch_clearing
    centre = x * TEXELS_PER_MM  # texel j covers [j, j + 1) / TEXELS_PER_MM
    columns = np.arange(band.shape[1])
    left_share = np.clip(centre - columns, 0.0, 1.0)  # the share of each texel left of the centre line
    return (band * left_share).sum(axis=1) / TEXELS_PER_MM, (band * (1.0 - left_share)).sum(axis=1) / TEXELS_PER_MM


def test_scratch_roughness_tears_each_edge_on_its_own(base_scene):
    scene, _ = base_scene
    left, right = scratch_widths(scene, 0.0)
    assert left + right == pytest.approx(0.6, abs=0.03)  # an even band of the scratch's width
    assert left == pytest.approx(right, abs=0.03)
    left, right = scratch_widths(scene, 0.4)
    # each edge lies off the centre line by 0.3 mm, +-40 % at most, with its mean kept
    for edge in (left, right):
        assert edge.max() - edge.min() > 0.06 and edge.min() > 0.3 * 0.6 - 0.03 and edge.max() < 0.3 * 1.4 + 0.03
        assert edge.mean() == pytest.approx(0.3, abs=0.05)
    # a torn strip, not a chain of beads: the two edges swell and narrow apart
    assert abs(np.corrcoef(left, right)[0, 1]) < 0.5


def test_scratches_scrape_as_much_as_asked_with_soft_edges_and_hazed_light(base_scene):
    """``artifacts.scratch_clearing`` is the share of the stain a scratch scrapes off, ``scratch_softness_mm`` widens
    the fade of its edges about the same outline (the scraped area kept), and ``scratch_haze`` dims the light through
    the scratched plastic, every channel alike, by that share where the scratch covers the layer; a lysed well's film
    shows no scrape."""
    scene, _ = base_scene
    texel = 1.0 / TEXELS_PER_MM

    def scraped(**artifacts):
        variant, well = one_scratch(scene, **artifacts)
        x, y = well.center_mm
        row = int(y * TEXELS_PER_MM)
        return variant, well, well_content(variant).scratched[row - 4: row + 4]  # across the middle of the scratch

    _, _, sharp = scraped(scratch_clearing=0.95)
    _, _, half = scraped(scratch_clearing=0.5)
    assert sharp.max() == pytest.approx(0.95) and half.max() == pytest.approx(0.5)
    np.testing.assert_allclose(half, sharp * 0.5 / 0.95, atol=1e-6)
    _, _, soft = scraped(scratch_clearing=0.95, scratch_softness_mm=0.3)

    def fading(band: np.ndarray) -> float:
        """Millimetres of the fade across the scratch, both edges together."""
        return float(((band > 0.05) & (band < 0.9)).sum(axis=1).mean() * texel)

    assert fading(sharp) < 2.5 * texel and fading(soft) > 0.3  # measured: 0.1 mm (a texel an edge) against 0.5
    assert soft.sum(axis=1).mean() * texel == pytest.approx(sharp.sum(axis=1).mean() * texel, abs=0.03)  # 0.57 mm
    clear, well, _ = scraped(scratch_clearing=0.95)
    hazed, _, _ = scraped(scratch_clearing=0.95, scratch_haze=0.4)
    x, y = well.center_mm
    middle = np.s_[int((y - 1.0) * TEXELS_PER_MM): int((y + 1.0) * TEXELS_PER_MM), int(x * TEXELS_PER_MM)]
    ratio = appearance.floor_transmittance(hazed, TEXELS_PER_MM)[middle] / appearance.floor_transmittance(
        clear, TEXELS_PER_MM)[middle]
    np.testing.assert_allclose(ratio, 0.6, atol=0.01)  # the scratch covers the middle: 1 - 0.4, grey
    beside = np.s_[int(y * TEXELS_PER_MM), int((x + 1.0) * TEXELS_PER_MM)]
    np.testing.assert_array_equal(appearance.floor_transmittance(hazed, TEXELS_PER_MM)[beside],
                                  appearance.floor_transmittance(clear, TEXELS_PER_MM)[beside])
    # a lysed well's film shows no scrape, hazed or not (the photos' lysed wells show none)
    lysed_hazed = one_lysed_well(hazed, well)
    unscratched = lysed_hazed.model_copy(update={"artifacts": lysed_hazed.artifacts.model_copy(
        update={"scratches": ()})})
    np.testing.assert_array_equal(appearance.floor_transmittance(lysed_hazed, TEXELS_PER_MM)[middle],
                                  appearance.floor_transmittance(unscratched, TEXELS_PER_MM)[middle])


def test_scratch_heaps_darken_a_scratchs_edges_only(base_scene):
    """``artifacts.scratch_heaps`` thickens the layer where a scratch's soft edge covers a texel in part (most where
    it covers half), by that relative density: neither the scraped middle nor the layer beside the scratch change."""
    scene, _ = base_scene
    scene = scene.model_copy(update={"stain": scene.stain.model_copy(update={"translucency": 0.0})})

    def density_across(**artifacts):
        """The layer's absorbance in blue (its density times a constant: no light passes unabsorbed) along a row
        across the scratch, and the scratched values there."""
        variant, well = one_scratch(scene, scratch_clearing=0.95, scratch_softness_mm=0.1, **artifacts)
        x, y = well.center_mm
        transmittance = appearance.floor_transmittance(variant, TEXELS_PER_MM)
        return -np.log(transmittance[int(y * TEXELS_PER_MM), :, 2]), well_content(variant).scratched[
            int(y * TEXELS_PER_MM)]

    plain, scratched = density_across()
    heaped, _ = density_across(scratch_heaps=2.0)
    cover = scratched / 0.95
    edge, middle, beside = (cover > 0.3) & (cover < 0.7), cover > 0.999, cover == 0.0
    assert edge.sum() >= 2 and middle.sum() >= 2
    # at a texel half covered the layer keeps half its density, then gains twice its density: 2.5 times as dense
    np.testing.assert_allclose(heaped[edge] / plain[edge], (1.0 - scratched[edge] + 2.0 * 4.0 * cover[edge] * (
        1.0 - cover[edge])) / (1.0 - scratched[edge]), rtol=0.02)
    assert (heaped[edge] > 2.0 * plain[edge]).all()
    np.testing.assert_allclose(heaped[middle], plain[middle], rtol=1e-5)
    np.testing.assert_array_equal(heaped[beside], plain[beside])


def test_scratch_ridge_lays_flaps_inside_one_edge_and_a_clump_past_the_end(base_scene):
    """``artifacts.scratch_ridge`` lays rolled-up cells over the scrape, on the side ``ridge_side`` of its centre
    line only: a ragged strip near that edge that the scrape does not clear, at full coverage that relative density
    of the layer, and a clump beside the scratch's end."""
    scene, _ = base_scene
    scene = scene.model_copy(update={"stain": scene.stain.model_copy(update={"translucency": 0.0})})
    variant, well = one_scratch(scene, scratch_clearing=0.95, scratch_ridge=2.0)
    x, y = well.center_mm
    rows = slice(int((y - 1.8) * TEXELS_PER_MM), int((y + 1.8) * TEXELS_PER_MM))
    column = int(x * TEXELS_PER_MM)  # the texel whose left edge is the centre line
    heaped = well_content(variant).heaped
    # the scratch runs down (+y): its left (+1) is -x; the ridge lies 0.6 half widths (0.18 mm) off the centre line
    left, right = heaped[rows, column - 8:column], heaped[rows, column:column + 8]
    assert right.max() == 0.0
    assert left.max() == pytest.approx(2.0)
    ridge = left[:, 8 - int(0.18 * TEXELS_PER_MM) - 1]
    assert ridge.min() < 0.5 * ridge.max()  # it varies along the scrape: flaps, not an even line
    # the scrape keeps what it did not clear, and the ridge gains twice the layer's density
    transmittance = appearance.floor_transmittance(variant, TEXELS_PER_MM)
    plain = appearance.floor_transmittance(one_scratch(scene, scratch_clearing=0.95)[0], TEXELS_PER_MM)
    scratched = well_content(variant).scratched
    full = np.argwhere(heaped[rows] == 2.0)[0] + (rows.start, 0)
    ratio = np.log(transmittance[(*full, 2)]) / np.log(plain[(*full, 2)])
    assert ratio == pytest.approx((1.0 - scratched[tuple(full)] + 2.0) / (1.0 - scratched[tuple(full)]), rel=0.01)
    # the clump: 0.15 mm to the left of the end and 0.15 mm past it, 0.18 mm in radius
    clump = int((y + 2.15) * TEXELS_PER_MM), int((x - 0.15) * TEXELS_PER_MM)
    assert heaped[clump] == pytest.approx(2.0)
    assert heaped[clump[0] + 8, clump[1]] == 0.0
    mirrored = one_scratch(scene, scratch_clearing=0.95, scratch_ridge=2.0)[0]
    mirrored = mirrored.model_copy(update={"artifacts": mirrored.artifacts.model_copy(update={
        "scratches": (mirrored.artifacts.scratches[0].model_copy(update={"ridge_side": -1}),)})})
    other = well_content(mirrored).heaped
    assert other[rows, column - 8:column].max() == 0.0 and other[rows, column:column + 8].max() == pytest.approx(2.0)


def test_pooling_thickens_each_well_toward_the_plates_tilt_only(base_scene):
    """``stain.pooling`` multiplies the layer's density by ``1 + pooling * p**2``, ``p`` the distance toward the side
    of ``rim_mottle_angle_deg`` over the radius where positive: the same in every well, nothing on the other side or
    across."""
    scene, _ = base_scene
    scene = scene.model_copy(update={"plaques": (), "stain": scene.stain.model_copy(update={
        "translucency": 0.0, "rim_mottle_angle_deg": 90.0})})
    pooled = scene.model_copy(update={"stain": scene.stain.model_copy(update={"pooling": 0.5})})
    plain, thick = (-np.log(appearance.floor_transmittance(s, TEXELS_PER_MM)[..., 2]) for s in (scene, pooled))
    radius = scene.plate.well_radius_mm
    for well in (scene.wells[0], scene.wells[7]):
        x, y = well.center_mm
        for dy in (0.3, 0.6, 0.9):
            below, above = ((int((y + sign * dy * radius) * TEXELS_PER_MM), int(x * TEXELS_PER_MM)) for sign in (1, -1))
            p = (below[0] + 0.5) / TEXELS_PER_MM - y
            assert thick[below] / plain[below] == pytest.approx(1.0 + 0.5 * (p / radius) ** 2, rel=1e-4)
            assert thick[above] == pytest.approx(plain[above], rel=1e-6)
        across = int(y * TEXELS_PER_MM), int((x + 0.9 * radius) * TEXELS_PER_MM)
        assert thick[across] == pytest.approx(plain[across], rel=1e-3)



def test_the_layers_blotches_dim_every_channel_alike_as_asked(base_scene):
    """``stain.unevenness_light`` multiplies a well floor's light, in all three channels, by ``1 - unevenness_light *
    unevenness * n``, ``n`` the noise of the layer's blotches there (the same noise that varies its density)."""
    scene, _ = base_scene
    scene = scene.model_copy(update={"plaques": ()})
    lit = scene.model_copy(update={"stain": scene.stain.model_copy(update={"unevenness_light": 0.5})})
    textures = scene_textures(scene)
    plain, dimmed = (appearance.floor_transmittance(s, TEXELS_PER_MM, textures) for s in (scene, lit))
    cell = textures.low_cell_mm
    for well in (scene.wells[0], scene.wells[7]):
        x, y = well.center_mm
        for dx, dy in ((0.0, 0.0), (3.1, -2.4), (-5.3, 4.7)):
            row, col = int((y + dy) * TEXELS_PER_MM), int((x + dx) * TEXELS_PER_MM)
            u, v = (col + 0.5) / TEXELS_PER_MM, (row + 0.5) / TEXELS_PER_MM
            blotch = grid_sample(textures.low_grid, u / cell, v / cell)
            expected = 1.0 - 0.5 * scene.stain.unevenness * blotch
            assert dimmed[row, col] / plain[row, col] == pytest.approx([expected] * 3, rel=1e-5)
    outside = int(2.0 * TEXELS_PER_MM), int(2.0 * TEXELS_PER_MM)  # the plate's corner: no well, no dimming
    assert dimmed[outside].tolist() == plain[outside].tolist() == [1.0, 1.0, 1.0]

def test_lysed_speckle_is_finer_than_the_grain(base_scene):
    scene, well = base_scene
    lysed = one_lysed_well(scene, well)
    lysed = lysed.model_copy(update={"stain": lysed.stain.model_copy(update={"lysed_foam": 0.0})})
    row, col = (int(c * TEXELS_PER_MM) for c in well.center_mm[::-1])
    reach = int(4 * TEXELS_PER_MM)

    def bands(**stain) -> tuple[float, float]:
        """Detail of the green transmittance near the centre finer than 0.1 mm (what a 0.1 mm blur removes) and
        between 0.1 and 0.5 mm."""
        variant = lysed.model_copy(update={"stain": lysed.stain.model_copy(update=stain)})
        green = appearance.floor_transmittance(variant, TEXELS_PER_MM)[..., 1].astype(np.float64)
        fine, coarse = (ndimage.gaussian_filter(green, s * TEXELS_PER_MM) for s in (0.1, 0.5))
        window = np.s_[row - reach: row + reach, col - reach: col + reach]
        return float((green - fine)[window].std()), float((fine - coarse)[window].std())

    smooth = bands(lysed_grain=0.0, lysed_speckle=0.0)
    speckled = bands(lysed_grain=0.0, lysed_speckle=0.8)
    grainy = bands(lysed_grain=0.8, lysed_speckle=0.0)
    assert speckled[0] > 4.0 * smooth[0]  # grains of about 0.15 mm: 8.4 times the finest detail, measured
    # the speckle's detail lies mostly below 0.1 mm (1.07 times what lies between 0.1 and 0.5 mm), the grain's flakes
    # above it (0.24 times)
    assert speckled[0] / speckled[1] > 2.5 * grainy[0] / grainy[1]


def test_lysed_foam_holes_what_a_lysed_well_keeps(base_scene):
    """``stain.lysed_foam`` multiplies a lysed well's remnant by ``1 - lysed_foam * hole``, ``hole`` the foam tile
    (0 to 1) read at ``lysed_foam_mm / FOAM_HOLE_TEXELS`` mm per texel: at 1, most of the well is bare where the
    holes lie, and the walls between them keep the remnant; the intact wells do not change."""
    scene, well = base_scene
    lysed = one_lysed_well(scene, well)
    lysed = lysed.model_copy(update={"stain": lysed.stain.model_copy(update={"lysed_foam": 0.0, "translucency": 0.0})})
    foamed = lysed.model_copy(update={"stain": lysed.stain.model_copy(update={"lysed_foam": 1.0, "lysed_foam_mm": 0.6})})
    plain, holed = (-np.log(appearance.floor_transmittance(s, TEXELS_PER_MM)[..., 2].astype(np.float64))
                    for s in (lysed, foamed))
    x, y = well.center_mm
    reach = int(6 * TEXELS_PER_MM)
    window = np.s_[int(y * TEXELS_PER_MM) - reach: int(y * TEXELS_PER_MM) + reach,
                   int(x * TEXELS_PER_MM) - reach: int(x * TEXELS_PER_MM) + reach]
    kept = holed[window] / plain[window]
    hole = scene_textures(foamed).foam_tile
    # the tile's share of texels deep inside a hole (0.64), against the well's share of texels left nearly bare
    # (0.58, read bilinearly at about one texel of the tile per texel of the floor)
    assert np.mean(kept < 0.05) == pytest.approx(np.mean(hole > 0.95), abs=0.1)
    assert np.mean(hole > 0.95) > 0.5  # holes cover most of the tile...
    assert np.mean(kept > 0.95) > 0.03  # ...and walls keep the whole remnant
    other = scene.wells[0]
    at = int(other.center_mm[1] * TEXELS_PER_MM), int(other.center_mm[0] * TEXELS_PER_MM)
    assert holed[at] == pytest.approx(plain[at], rel=1e-6)


def test_the_foam_tile_is_merged_round_holes_with_thin_walls():
    """:func:`foam_tile`: periodic holes of median radius ``FOAM_HOLE_TEXELS``, no centre inside another hole,
    covering most of the tile; where two meet a thin wall keeps stain."""
    tile = foam_tile(np.random.default_rng(7))
    assert tile.shape == (FOAM_TILE, FOAM_TILE) and tile.dtype == np.float32
    assert tile.min() >= 0.0 and tile.max() == pytest.approx(1.0)
    assert np.array_equal(tile, foam_tile(np.random.default_rng(7)))
    bare = tile > 0.95
    assert 0.55 < bare.mean() < 0.85  # most is cleared; walls and islands of stain keep the rest
    labels, count = ndimage.label(bare, structure=np.ones((3, 3)))
    # the walls split the cleared area into holes, one per thrown disc or so, of about the median hole's area
    median_area = np.median(np.bincount(labels.ravel())[1:])
    assert count > 0.5 * tile.size / (np.pi * FOAM_HOLE_TEXELS**2 * 2.0)
    assert 0.3 < median_area / (np.pi * FOAM_HOLE_TEXELS**2) < 1.5


def test_the_lysed_cloud_keeps_changing_along_the_whole_plate():
    """A lysed well's cloud reads the unevenness grid :data:`LYSED_CLOUD_SHIFT` cells to the right, wrapping past
    the grid's right edge: along the plate's whole length it keeps changing (clamped at the edge, it stood still over
    the wells right of about 83 mm, a flat stretch of remnant)."""
    scene = sample_scene(load_config("high"), 5)
    textures = scene_textures(scene)
    along = np.linspace(0.0, scene.plate.length_mm, 4000)
    lumps = np.array([appearance.cloud_lumps(textures.low_grid, u, 40.0, textures.low_cell_mm) for u in along])
    still = np.abs(np.diff(lumps)) < 1e-9
    assert not (still[1:] & still[:-1]).any()  # steps of 0.03 mm in cells of several mm: never two in a row unchanged
    clamped = np.array([grid_sample(textures.low_grid, u / textures.low_cell_mm + appearance.LYSED_CLOUD_SHIFT,
                                    40.0 / textures.low_cell_mm) for u in along])
    assert (np.abs(np.diff(clamped)) < 1e-9).sum() > 500  # what the clamped read did: standing still for mm


def test_panel_shade_darkens_the_floors_toward_the_light_panels_edge():
    """``background.panel_shade``: a well's floor keeps ``1 - s`` of its light at its rim nearest the light panel's
    edge, ``s = panel_shade * exp(-d / panel_shade_reach_mm)`` for its rim ``d`` mm inside that edge, the loss fading
    to none ``panel_shade_width_mm`` inward (a smoothstep); nothing on a desk. Both renderers draw it: the raster
    renderer from the same table, Blender from this floor texture."""
    shade = {"background.kind": "lightbox", "background.panel_below": 1.0, "background.panel_margin_y_mm": 0.0,
             "background.panel_shade": 0.8, "background.panel_shade_reach_mm": 20.0,
             "background.panel_shade_width_mm": 6.0, "wells.emptied": 0.0}
    shaded = sample_scene(load_config("high", overrides=shade), 4)
    plain = sample_scene(load_config("high", overrides={**shade, "background.panel_shade": 0.0}), 4)
    plate, wells = shaded.plate, appearance.wells_by_grid(shaded)
    table = appearance.panel_shades(shaded, wells)
    # the panel's edge is the plate's bottom edge (plate y = its width): the bottom row's rims lie 5.7 mm inside it
    bottom_row, middle_row = table[(plate.rows - 1) * plate.cols], table[(plate.rows - 2) * plate.cols]
    inside = plate.width_mm - wells[(plate.rows - 1) * plate.cols].center_mm[1] - plate.well_radius_mm
    assert bottom_row[0] == pytest.approx(0.8 * np.exp(-inside / 20.0))
    assert middle_row[0] == pytest.approx(bottom_row[0] * np.exp(-plate.pitch_mm / 20.0))
    assert tuple(bottom_row[1:]) == (0.0, 1.0, 6.0)  # toward +y, the plate's bottom edge, in plate coordinates

    k = TEXELS_PER_MM  # the same scene but for the shade: the floors' ratio is the light the shade leaves
    ratio = appearance.floor_transmittance(shaded, k) / appearance.floor_transmittance(plain, k)
    well = wells[(plate.rows - 1) * plate.cols + 1]
    column = int(well.center_mm[0] * k)
    for below_centre_mm, expected in ((-5.0, 0.0), (0.0, 0.0), (plate.well_radius_mm - 6.0, 0.0),
                                      (plate.well_radius_mm - 3.0, 0.5), (plate.well_radius_mm - 0.1, 0.99)):
        row = int((well.center_mm[1] + below_centre_mm) * k)
        x = expected  # the smoothstep's argument at the texel's centre, near enough for these places
        loss = bottom_row[0] * x * x * (3 - 2 * x)
        assert ratio[row, column] == pytest.approx(1.0 - loss, abs=0.02)
    # a desk has no panel: the same draws on a desk shade nothing
    desk = shaded.model_copy(update={"background": shaded.background.model_copy(update={"kind": "desk"})})
    assert not appearance.panel_shades(desk, wells).any()


def test_crowd_thinning_thins_the_layer_of_a_crowded_well_by_the_share_its_plaques_cover(base_scene):
    """``stain.crowd_thinning``: a well's layer density times ``exp(-crowd_thinning * share)``, ``share`` the part
    of its floor its plaques' discs cover (at most 1); the wells without plaques, and lysed ones, keep theirs. The
    table both renderers draw from holds it, so the floor texture of the crowded well is paler in every channel."""
    scene, well = base_scene
    radius = scene.plate.well_radius_mm
    crowd = tuple(Plaque(id=i + 1, well=well.id, center_mm=(well.center_mm[0] + dx, well.center_mm[1] + dy),
                         radius_mm=1.5, fourier=(), softness=0.2, clearness=1.0)
                  for i, (dx, dy) in enumerate([(-5, -5), (5, -5), (-5, 5), (5, 5)]))
    share = 4 * 1.5**2 / radius**2
    lysed = next(w for w in scene.wells if w.id != well.id)
    crowded = scene.model_copy(update={
        "plaques": crowd + (Plaque(id=5, well=lysed.id, center_mm=lysed.center_mm, radius_mm=3.0, fourier=(),
                                   softness=0.2, clearness=1.0),),
        "wells": tuple(w.model_copy(update={"lysed": w.id == lysed.id, "emptied": False}) for w in scene.wells)})
    thinned = crowded.model_copy(update={"stain": crowded.stain.model_copy(update={"crowd_thinning": 4.0})})
    wells = appearance.wells_by_grid(thinned)
    drawn = np.array([w.stain.density for w in wells])
    np.testing.assert_array_equal(appearance.layer_densities(crowded, wells), drawn)
    expected = drawn.copy()
    expected[[w.id for w in wells].index(well.id)] *= np.exp(-4.0 * share)
    np.testing.assert_allclose(appearance.layer_densities(thinned, wells), expected)

    k = TEXELS_PER_MM
    col, row = int(well.center_mm[0] * k), int(well.center_mm[1] * k)  # the centre, between the four plaques
    before, after = (appearance.floor_transmittance(s, k)[row, col] for s in (crowded, thinned))
    assert np.all(after > before)
    # the red and blue absorbance at the centre fall by the factor the density does (the green, nearly all absorbed,
    # is held up by the share of light the layer lets through, stain.translucency)
    np.testing.assert_allclose((np.log(after) / np.log(before))[[0, 2]], np.exp(-4.0 * share), rtol=0.02)
