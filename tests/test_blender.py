"""The Blender backend: real tiny renders in a worker, masks against the raster renderer's, the worker pool's
crash / timeout / recycling behaviour (with a stand-in worker), .blend export and the ``scene export`` command."""

from __future__ import annotations

import json
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage
from typer.testing import CliRunner

from _geometry import distance_to_top_edges, past_top_edge, pixel_centres_mm, wall_band
from platesynth.errors import ParameterError
from platesynth.render.blender import (
    BlenderScriptError,
    BlenderWorkerError,
    BlenderWorkerPool,
    bpy_available,
    export_blend,
    render_blender,
)
from platesynth.render.blender.describe import camera_pose
from platesynth.render.masks import renumber
from platesynth.render.raster import camera_view, render_raster
from platesynth.scene import load_config, sample_scene

SIZE = (160, 120)
SAMPLES = 2
PLAQUE_IOU = 0.9
"""Stated agreement: the union of plaque pixels in Blender's and the raster renderer's masks overlaps at least this
much (intersection over union) at 160x120; at 1024x768 it is about 0.99 (benchmarks/bench_blender.py)."""

needs_bpy = pytest.mark.skipif(not bpy_available(), reason="bpy (Blender 5.0.1 as a Python module) is not installed here: pip install 'platesynth[blender]'")


def scene_with_plaques(seed: int = 5, **overrides):
    settings = {"plaques.negative_plate": 0.0, "plaques.top_count": 120, "plaques.lysis_count": 1000}
    return sample_scene(load_config("high", overrides=settings | overrides), seed)


@pytest.fixture(scope="module")
def pool(tmp_path_factory):
    with BlenderWorkerPool(home=tmp_path_factory.mktemp("blender-home"), timeout=240) as shared_pool:
        yield shared_pool


@pytest.fixture(scope="module")
def rendered(pool):
    scene = scene_with_plaques()
    return scene, render_blender(scene, SIZE, samples=SAMPLES, pool=pool), render_raster(scene, SIZE)


# ---------------------------------------------------------------------------------------------- without bpy


def test_renumber_keeps_order_and_closes_gaps():
    mask = np.array([[0, 7, 7], [3, 0, 12]], dtype=np.uint16)
    assert renumber(mask).tolist() == [[0, 2, 2], [1, 0, 3]]
    assert renumber(np.zeros((2, 2), np.uint16)).tolist() == [[0, 0], [0, 0]]


@pytest.mark.parametrize("below", [0.0, 1.0])
def test_camera_pose_reproduces_the_raster_homography(below):
    scene = sample_scene(load_config("high", overrides={"camera.from_below": below, "camera.tilt_deg": 6.0, "camera.rotation_deg": 4.0}), 3)
    view = camera_view(scene, 320, 240)
    matrix_world, focal, principal = camera_pose(scene, view)
    points = np.array([[5.0, 7.0], [120.0, 80.0], [64.0, 40.0]])
    world = np.column_stack([points[:, 0], -points[:, 1], np.zeros(3), np.ones(3)])
    camera = (np.linalg.inv(matrix_world) @ world.T).T  # Blender camera: looks along -z, y up
    pixels = np.column_stack([principal[0] + focal * camera[:, 0] / -camera[:, 2], principal[1] - focal * camera[:, 1] / -camera[:, 2]])
    np.testing.assert_allclose(pixels, view.project(points), atol=1e-6)
    # seen from below the camera is under the plate (negative z), from above over it
    assert np.sign(matrix_world[2, 3]) == (-1 if below else 1)


def _fake_worker(tmp_path: Path) -> list[str]:
    """A stand-in worker speaking the real protocol: it crashes, hangs or answers on request."""
    script = tmp_path / "fake_worker.py"
    script.write_text(
        textwrap.dedent(
            """
            import json, os, sys, time
            marker = sys.argv[1]
            print(json.dumps({"event": "ready", "pid": os.getpid()}), flush=True)
            for line in sys.stdin:
                request = json.loads(line)
                op = request["op"]
                if op == "quit":
                    break
                if op == "crash" or (op == "crash_once" and not os.path.exists(marker)):
                    open(marker, "w").close()
                    sys.stderr.write("fake worker dying on purpose\\n"); sys.stderr.flush()
                    os.abort()
                if op == "hang":
                    time.sleep(60)
                print(json.dumps({"ok": True, "pid": os.getpid(), "home": os.environ["HOME"]}), flush=True)
            """
        )
    )
    return [sys.executable, str(script), str(tmp_path / "crashed-once")]


def test_a_crash_is_retried_once_on_a_fresh_worker(tmp_path):
    with BlenderWorkerPool(command=_fake_worker(tmp_path), home=tmp_path / "home") as fake:
        reply = fake.request({"op": "crash_once"})
        assert reply["ok"] and fake.workers_started == 2
        assert reply["home"] == str(tmp_path / "home")  # Blender's home-directory files go where the tool says


def test_repeated_crashes_fail_with_blenders_log(tmp_path):
    with BlenderWorkerPool(command=_fake_worker(tmp_path), home=tmp_path / "home") as fake:
        with pytest.raises(BlenderWorkerError, match="failed 2 times.*SIGABRT") as failure:
            fake.request({"op": "crash"})
        assert len(failure.value.attempts) == 2
        assert "fake worker dying on purpose" in failure.value.log
        assert fake.request({"op": "ping"})["ok"]  # the pool goes on with a new worker


def test_a_hanging_render_times_out_and_is_retried(tmp_path):
    with BlenderWorkerPool(command=_fake_worker(tmp_path), home=tmp_path / "home", timeout=0.5) as fake:
        with pytest.raises(BlenderWorkerError, match="timed out") as failure:
            fake.request({"op": "hang"})
        assert len(failure.value.attempts) == 2 and fake.workers_started == 2


def test_workers_are_replaced_every_n_requests(tmp_path):
    with BlenderWorkerPool(command=_fake_worker(tmp_path), home=tmp_path / "home", max_renders_per_worker=2) as fake:
        pids = [fake.request({"op": "ping"})["pid"] for _ in range(5)]
    assert pids[0] == pids[1] != pids[2] == pids[3] != pids[4]


def test_pool_settings_from_the_environment_are_checked(monkeypatch):
    from platesynth.render.blender.pool import setting_from_env

    monkeypatch.setenv("PLATESYNTH_BLENDER_MAX_RENDERS", "20")
    assert setting_from_env("PLATESYNTH_BLENDER_MAX_RENDERS", 50) == 20
    monkeypatch.setenv("PLATESYNTH_BLENDER_MAX_RENDERS", "2.5")
    with pytest.raises(ParameterError, match="PLATESYNTH_BLENDER_MAX_RENDERS must be a positive integer"):
        setting_from_env("PLATESYNTH_BLENDER_MAX_RENDERS", 50)
    monkeypatch.delenv("PLATESYNTH_BLENDER_TIMEOUT", raising=False)
    assert setting_from_env("PLATESYNTH_BLENDER_TIMEOUT", 300.0) == 300.0


def test_bad_arguments_are_refused_before_blender_starts():
    scene = scene_with_plaques()
    with pytest.raises(ParameterError, match="engine"):
        render_blender(scene, SIZE, engine="BLENDER_EEVEE_NEXT")
    with pytest.raises(ParameterError, match="size"):
        render_blender(scene, (8, 8))
    with pytest.raises(ParameterError, match=r"\.blend"):
        export_blend(scene, "plate.png")


# ---------------------------------------------------------------------------------------------- with bpy


@needs_bpy
def test_masks_are_exact_integers_and_agree_with_the_raster_renderer(rendered):
    scene, blender, raster = rendered
    width, height = SIZE
    assert blender.image.shape == (height, width, 3) and blender.image.dtype == np.uint8
    assert blender.wells.dtype == np.uint8 and blender.plaques.dtype == np.uint16
    assert blender.wells.shape == blender.plaques.shape == (height, width)
    # the same wells, at the same places
    assert set(np.unique(blender.wells)) == set(np.unique(raster.wells)) == {0} | {w.id for w in scene.wells}
    assert (blender.wells == raster.wells).mean() > 0.99
    # visible plaques numbered 1..m without gaps, each inside one well
    ids = np.unique(blender.plaques)
    assert ids[0] == 0 and ids[1:].tolist() == list(range(1, len(ids)))
    assert len(ids) > 20
    both, either = (blender.plaques > 0) & (raster.plaques > 0), (blender.plaques > 0) | (raster.plaques > 0)
    assert both.sum() / either.sum() >= PLAQUE_IOU
    assert not ((blender.plaques > 0) & (blender.wells == 0)).any()
    # counts from the masks: per well close to the raster renderer's
    counts, raster_counts = blender.plaque_counts(), raster.plaque_counts()
    assert counts.keys() == raster_counts.keys()
    assert sum(counts.values()) == len(ids) - 1
    for well, count in raster_counts.items():
        assert abs(counts[well] - count) <= max(2, 0.1 * count), (well, counts[well], count)


@needs_bpy
def test_no_well_id_spills_outside_its_well(rendered):
    scene, blender, _ = rendered
    view = camera_view(scene, *SIZE)
    u, v = pixel_centres_mm(view)
    pixel_mm = 1.0 / view.px_per_mm
    for well in scene.wells:
        inside = blender.wells == well.id
        distance = np.hypot(u[inside] - well.center_mm[0], v[inside] - well.center_mm[1])
        assert distance.max() <= scene.plate.well_radius_mm + pixel_mm, well.label


@needs_bpy
def test_every_plaque_in_the_mask_is_visible_in_the_image(rendered):
    _, blender, _ = rendered
    brightness = blender.image.astype(np.float64).mean(axis=2)
    for plaque in range(1, int(blender.plaques.max()) + 1):
        inside = blender.plaques == plaque
        if inside.sum() < 3:  # a pixel or two: too few to tell from the texture
            continue
        well = np.bincount(blender.wells[inside]).argmax()
        stained = (blender.wells == well) & (blender.plaques == 0)
        assert brightness[inside].mean() > brightness[stained].mean(), plaque


@needs_bpy
def test_an_error_inside_blender_is_an_error_for_the_user(pool):
    with pytest.raises(BlenderScriptError, match="KeyError"):
        pool.request({"op": "render", "scene": {"scene": {}, "view": {}}, "options": {}, "out_dir": str(pool.scratch / "x")})
    with pytest.raises(BlenderScriptError, match="engine must be one of"):
        from platesynth.render.blender.describe import describe_scene

        texture_dir = pool.scratch / "y"
        texture_dir.mkdir()
        request = {"scene": describe_scene(scene_with_plaques(), SIZE, texture_dir), "options": {"engine": "BLENDER_EEVEE_NEXT"}}
        pool.request({"op": "render", "out_dir": str(pool.scratch / "y"), **request})
    reply = pool.request({"op": "ping"})  # the same worker carries on
    assert reply["ok"] and reply["blender"].startswith("5.0")


@needs_bpy
def test_export_writes_a_blend_file_and_the_cli_command(pool, tmp_path):
    from platesynth.cli import app

    scene = scene_with_plaques()
    target = export_blend(scene, tmp_path / "plate.blend", SIZE, pool=pool)
    assert target.stat().st_size > 10_000
    assert [p.name for p in tmp_path.iterdir()] == ["plate.blend"]  # no temporary file left behind

    saved = tmp_path / "scene.json"
    saved.write_text(json.dumps(scene.model_dump(mode="json")))
    runner = CliRunner()
    # a new pool in this process for the command: it builds the same scene from the saved JSON
    result = runner.invoke(app, ["scene", "export", "--scene", str(saved), "--out", str(tmp_path / "again.blend"), "--size", "160x120"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "again.blend").stat().st_size > 10_000
    refused = runner.invoke(app, ["scene", "export", "--out", str(tmp_path / "plate.png")])
    assert refused.exit_code == 1 and "must end in .blend" in refused.output


@needs_bpy
def test_the_image_matches_the_raster_renderers_light_on_floors_and_plastic(rendered):
    """The same light model: floors (away from plaques) and the plastic between the wells come out as bright as
    in the raster renderer, within a few levels; no speckle (paths ended at random) darkens the plastic."""
    _, blender, raster = rendered
    floors = ndimage.binary_erosion(raster.wells > 0, iterations=3) & ~ndimage.binary_dilation(raster.plaques > 0, iterations=3)
    plastic = ~ndimage.binary_dilation(raster.wells > 0, iterations=4)
    plastic[:8], plastic[-8:], plastic[:, :8], plastic[:, -8:] = False, False, False, False
    for region in (floors, plastic):
        difference = blender.image[region].astype(np.float64).mean(axis=0) - raster.image[region].mean(axis=0)
        assert np.abs(difference).max() < 6.0, difference
    luminance = blender.image.astype(np.float64).mean(axis=2)[plastic]
    assert np.percentile(luminance, 1) > 0.75 * np.median(luminance)


@needs_bpy
def test_the_stain_and_lysed_wells_are_the_raster_renderers(pool):
    """Both renderers read the scene's noise textures: the same lysed remnants, stain unevenness and plaque fray
    at the same places, so the images agree pixel by pixel inside the wells, not only on average."""
    overrides = {"plaques.lysis_count": 1, "plaques.negative_plate": 0.0, "stain.pale_plates": 0.0}
    # (a pale plate would leave the pale lysed colour below nothing to change)
    scene = sample_scene(load_config("high", overrides=overrides), 1000)
    assert any(w.lysed for w in scene.wells)
    size = (320, 240)
    blender, raster = render_blender(scene, size, samples=SAMPLES, pool=pool), render_raster(scene, size)
    lysed_ids = [w.id for w in scene.wells if w.lysed]
    inside = ndimage.binary_erosion(np.isin(raster.wells, lysed_ids), iterations=2)
    # a 1-pixel blur evens out what differs at the pixel level: anti-aliasing, each backend's own sensor noise
    b, r = (ndimage.gaussian_filter(image.astype(np.float64).mean(axis=2), 1.0)[inside] for image in (blender.image, raster.image))
    assert np.corrcoef(b, r)[0, 1] > 0.95  # 0.985 measured; 0.45 with Blender's own noise textures
    assert np.abs(b - r).mean() < 10.0  # 5.7 levels measured; 30 with Blender's own remnant model
    # the pale colour of the remnants (stain.lysed_paleness) reaches Blender through the same floor texture
    pale = scene.model_copy(update={"stain": scene.stain.model_copy(
        update={"lysed_paleness": 1.0, "lysed_hue_deg": 240.0, "lysed_saturation": 0.5})})
    blender_pale, raster_pale = render_blender(pale, size, samples=SAMPLES, pool=pool), render_raster(pale, size)
    change = [(p.image[inside].astype(np.float64).mean(axis=0) - u.image[inside].mean(axis=0))
              for p, u in ((blender_pale, blender), (raster_pale, raster))]
    assert np.abs(change[1]).max() > 5.0, change  # the colour moved: green +9.0 levels
    assert np.abs(change[0] - change[1]).max() < 0.25 * np.abs(change[1]).max(), change  # 0.3 levels apart measured


def _paler_in_both(pool, before_scene, after_scene, size=(320, 240)):
    """How much paler ``after_scene`` is than ``before_scene`` at every pixel (8-bit levels, channels averaged,
    smoothed over a pixel), in Blender and in the raster renderer."""
    changes = []
    for render in (lambda scene: render_blender(scene, size, samples=SAMPLES, pool=pool), lambda scene: render_raster(scene, size)):
        before, after = render(before_scene), render(after_scene)
        changes.append(ndimage.gaussian_filter((after.image.astype(np.float64) - before.image).mean(axis=2), 1.0))
    return changes


@needs_bpy
def test_the_rim_tears_are_the_raster_renderers(pool):
    """``artifacts.rim_tears`` are scratches of the scene, which Blender takes from the same floor texture: the same
    pixels grow paler in both renderers."""
    overrides = {"plaques.negative_plate": 1.0, "wells.emptied": 0.0, "artifacts.rim_tear_width_mm": [1.5, 2.0]}
    plain, torn = (sample_scene(load_config("high", overrides=overrides | {"artifacts.rim_tears": rate}), 7)
                   for rate in (0.0, 2.0))
    assert len(torn.artifacts.scratches) > len(plain.artifacts.scratches)
    changes = _paler_in_both(pool, plain, torn)
    torn_pixels = changes[1] > 8.0  # paler by 8 levels or more in the raster renderer
    assert torn_pixels.sum() > 100  # 879 measured
    assert np.corrcoef(changes[0].ravel(), changes[1].ravel())[0, 1] > 0.9  # 0.985 measured
    assert changes[0][torn_pixels].mean() == pytest.approx(changes[1][torn_pixels].mean(), rel=0.15)  # 32.3, 30.2


@needs_bpy
def test_the_smears_are_the_raster_renderers(pool):
    """``artifacts.smears`` are drawn into the floor texture Blender shows, as the raster renderer draws them: the same
    pixels grow darker in both renderers."""
    overrides = {"plaques.negative_plate": 1.0, "wells.emptied": 0.0, "artifacts.smear_width_mm": [1.0, 1.5]}
    plain, smeared = (sample_scene(load_config("high", overrides=overrides | {"artifacts.smears": rate}), 7)
                      for rate in (0.0, 1.5))
    assert smeared.artifacts.smears and not plain.artifacts.smears
    changes = [-change for change in _paler_in_both(pool, plain, smeared)]
    dark_pixels = changes[1] > 8.0  # darker by 8 levels or more in the raster renderer
    assert dark_pixels.sum() > 100
    assert np.corrcoef(changes[0].ravel(), changes[1].ravel())[0, 1] > 0.9
    assert changes[0][dark_pixels].mean() == pytest.approx(changes[1][dark_pixels].mean(), rel=0.15)


def _scene_without_post():
    """A plate without plaques in a bright exposure (so that bloom has bright areas to glow around), and the same
    with every post-processing effect and the optical blur off (and sharpening per channel, noise per pixel, when
    switched on)."""
    from platesynth.scene.concrete import Effect

    scene = sample_scene(load_config("high", overrides={"plaques.negative_plate": 1.0, "lighting.exposure_ev": 0.0}), 2)
    switches = {name: effect.model_copy(update={"enabled": False}) for name, effect in scene.post if isinstance(effect, Effect)}
    switches |= {"sharpen_luma": 0.0, "sharpen_threshold": 0.0, "noise_grain_px": 0.0, "black_level": 0.0}
    return scene, scene.model_copy(update={"post": scene.post.model_copy(update=switches),
                                           "camera": scene.camera.model_copy(update={"defocus_px": 0.0})})


@needs_bpy
def test_the_compositor_post_processing_is_the_raster_renderers(pool):
    """Each deterministic effect of the compositor, sharpening stronger than 1 included, changes Blender's image
    as :func:`platesynth.render.postprocess.apply_post` changes it."""
    from platesynth.render import postprocess
    from platesynth.render.raster import REFERENCE_WIDTH
    from platesynth.scene.concrete import Effect
    from platesynth.scene.streams import scene_rng

    scene, bare = _scene_without_post()
    size = (320, 240)
    plain = render_blender(bare, size, samples=SAMPLES, pool=pool).image
    effects = {"brightness": 0.1, "clarity": 0.4, "motion_blur": 6.0, "chromatic_aberration": 3.0, "bloom": 0.4, "sharpen": 1.8}
    variants = {name: {name: Effect(enabled=True, strength=strength)} for name, strength in effects.items()}
    variants["sharpen_luma"] = {"sharpen": Effect(enabled=True, strength=1.8), "sharpen_luma": 1.0}
    variants["sharpen_threshold"] = {"sharpen": Effect(enabled=True, strength=1.8), "sharpen_threshold": 4.0}
    variants["black_level"] = {"black_level": 0.06}
    colour_of_change, change_of = {}, {}
    for name, update in variants.items():
        post = bare.post.model_copy(update=update)
        blender = render_blender(bare.model_copy(update={"post": post}), size, samples=SAMPLES, pool=pool).image.astype(np.float64)
        expected = postprocess.to_uint8(postprocess.apply_post(plain.astype(np.float32) / 255, post, scene_rng(scene.seed, "post"), size[0] / REFERENCE_WIDTH))
        change, expected_change = np.abs(blender - plain).mean(), np.abs(expected.astype(np.float64) - plain).mean()
        assert expected_change > 0.3, name
        assert abs(change - expected_change) < 0.15 * expected_change, (name, change, expected_change)
        assert np.abs(blender - expected).mean() < 0.35 * expected_change + 0.3, name
        colour_of_change[name] = np.abs(np.diff(blender - plain, axis=2)).mean()  # how unequal the channels' changes are
        change_of[name] = change
    # sharpening the luminance changes every channel alike (0.31 levels between neighbouring channels, 2.10 for
    # sharpening each channel, measured)
    assert colour_of_change["sharpen_luma"] < 0.3 * colour_of_change["sharpen"], colour_of_change
    # coring leaves the flat stain's detail alone: the change is smaller than sharpening everything
    assert change_of["sharpen_threshold"] < 0.8 * change_of["sharpen"], change_of


@needs_bpy
def test_the_compositor_sensor_noise_is_the_raster_renderers(pool):
    """The sensor noise has the same sd in both renderers, each pixel its own without ``post.noise_grain_px`` and
    clumped into grains as much with it (each renderer draws its own noise, so its statistics are compared)."""
    from platesynth.scene.concrete import Effect

    _, bare = _scene_without_post()
    size = (320, 240)
    plain = {"raster": render_raster(bare, size).image, "blender": render_blender(bare, size, samples=SAMPLES, pool=pool).image}
    statistics = {}
    for grain in (0.0, 3.0):  # 0.94 px at this width
        post = bare.post.model_copy(update={"noise": Effect(enabled=True, strength=8.0), "noise_grain_px": grain})
        noisy = bare.model_copy(update={"post": post})
        for name, image in (("raster", render_raster(noisy, size).image), ("blender", render_blender(noisy, size, samples=SAMPLES, pool=pool).image)):
            noise = image.astype(np.float64).mean(axis=2) - plain[name].astype(np.float64).mean(axis=2)
            neighbours = np.corrcoef(noise[:, 1:].ravel(), noise[:, :-1].ravel())[0, 1]
            statistics[name, grain] = (noise.std(), neighbours)
    # measured: sd 6.16 and 6.17 levels in the raster renderer, 5.56 and 5.67 in Blender; the correlation of
    # neighbouring pixels 0.00 without grains, 0.75 in both with them (exp(-1 / (4 * 0.94**2)) = 0.75 for blurred
    # white noise)
    for grain in (0.0, 3.0):
        (raster_sd, raster_r), (blender_sd, blender_r) = statistics["raster", grain], statistics["blender", grain]
        assert abs(blender_sd - raster_sd) < 0.15 * raster_sd, statistics
        assert abs(blender_r - raster_r) < 0.1, statistics
    assert statistics["raster", 0.0][1] < 0.1 and statistics["raster", 3.0][1] > 0.65, statistics


@needs_bpy
def test_the_skirt_is_shaded_as_in_the_raster_renderer(rendered):
    """The flange along the plate's outline passes up to 25 % less light in both renderers (Blender's plastic
    reads the same signed distance to the outline)."""
    scene, blender, raster = rendered
    view = camera_view(scene, *SIZE)
    u, v = pixel_centres_mm(view)
    plate = scene.plate
    qx = np.abs(u - plate.length_mm / 2) - (plate.length_mm / 2 - plate.corner_radius_mm)
    qy = np.abs(v - plate.width_mm / 2) - (plate.width_mm / 2 - plate.corner_radius_mm)
    signed = np.hypot(np.maximum(qx, 0), np.maximum(qy, 0)) + np.minimum(np.maximum(qx, qy), 0) - plate.corner_radius_mm
    pixel_mm = 1.0 / view.px_per_mm
    skirt = (signed < -pixel_mm) & (signed > -plate.skirt_mm + pixel_mm) & (raster.wells == 0)
    assert skirt.sum() > 50
    difference = blender.image[skirt].astype(np.float64).mean(axis=0) - raster.image[skirt].mean(axis=0)
    # 3.95 levels on the scene of the fifteenth session's high, 4.02 on the sixteenth's (its scratches' draws moved
    # the scene; Blender darker in all three channels, by about 5 levels more than 2.5 pixels inside the outline): a
    # gap between the renderers that this bound records rather than hides (docs/blender.md)
    assert np.abs(difference).max() < 4.5, difference


@needs_bpy
def test_the_walls_top_edge_through_the_floor_is_the_raster_renderers(pool):
    """``plate.top_edge_through_floor`` darkens the arc of the walls' top edge across the floors as much in
    Blender (the rim films' share hidden behind the floors) as in the raster renderer. Blender places the edge in
    3D, the raster renderer with a parallax about the camera's axis: the arcs lie up to two pixels apart, so the
    darkening is compared over a band around them."""
    size = (480, 360)
    settings = {"plaques.negative_plate": 1.0, "camera.distance_mm": 180.0, "wells.emptied": 0.0, "post.jpeg": 0.0}
    hidden, shown = (sample_scene(load_config("high", overrides=settings | {"plate.top_edge_through_floor": share}), 6) for share in (0.0, 1.0))
    to_edge, on_floor, pixel_mm = distance_to_top_edges(shown, size)
    band = on_floor & (to_edge < 3 * pixel_mm)
    darkening = {}
    for name, draw in (("raster", render_raster), ("blender", lambda s, z: render_blender(s, z, samples=SAMPLES, pool=pool))):
        before, after = (draw(scene, size).image.astype(np.float64).mean(axis=2) for scene in (hidden, shown))
        darkening[name] = (before - after)[band].mean()
    assert darkening["raster"] > 0.5, darkening  # levels over the band; 0.92 measured, 0.85 in Blender
    assert abs(darkening["blender"] - darkening["raster"]) < 0.3 * darkening["raster"], darkening


@needs_bpy
def test_the_smeared_top_edge_is_the_raster_renderers(pool):
    """``plate.top_edge_blur_mm`` smears the outlines of the walls' top edge as much in Blender (the rim material's
    coverage) as in the raster renderer: lighter on the line, darker beside it, as dark in all. Blender's top edge
    lies 2-3 pixels from the raster renderer's here (the walls' parallax, as in the test above), so the change is
    compared over a band 5 pixels wide on either side."""
    size = (480, 360)
    settings = {"plaques.negative_plate": 1.0, "camera.distance_mm": 2000.0, "wells.emptied": 0.0, "post.jpeg": 0.0,
                "plate.top_edge_through_floor": 0.0}
    sharp, smeared = (sample_scene(load_config("high", overrides=settings | {"plate.top_edge_blur_mm": blur}), 6)
                      for blur in (0.0, 0.8))
    to_edge, on_floor, pixel_mm = distance_to_top_edges(sharp, size)
    band = ~on_floor & (to_edge < 5 * pixel_mm)
    lighter, darker = {}, {}
    for name, draw in (("raster", render_raster), ("blender", lambda s, z: render_blender(s, z, samples=SAMPLES, pool=pool))):
        before, after = (draw(scene, size).image.astype(np.float64).mean(axis=2) for scene in (sharp, smeared))
        change = (after - before)[band]
        lighter[name], darker[name] = np.clip(change, 0, None).mean(), np.clip(change, None, 0).mean()
        assert np.abs(after - before)[~on_floor & (to_edge > 8 * pixel_mm)].mean() < 0.05  # nothing else moves
    # levels, mean over the band: +1.58 and -1.56 measured in the raster renderer, +1.87 and -1.92 in Blender
    assert lighter["raster"] > 1.0 and abs(lighter["raster"] + darker["raster"]) < 0.2 * lighter["raster"]
    assert abs(lighter["blender"] - lighter["raster"]) < 0.35 * lighter["raster"], (lighter, darker)
    assert abs(darker["blender"] - darker["raster"]) < 0.35 * lighter["raster"], (lighter, darker)


@needs_bpy
def test_the_band_over_the_walls_is_the_raster_renderers(pool):
    """``plate.wall_band`` darkens the plastic over the walls' thickness as much in Blender (the band's film) as in
    the raster renderer."""
    size = (480, 360)
    settings = {"plaques.negative_plate": 1.0, "wells.emptied": 0.0, "post.jpeg": 0.0,
                "plate.top_edge_through_floor": 0.0}
    bright, dark = (sample_scene(load_config("high", overrides=settings | {"plate.wall_band": share}), 6)
                    for share in (0.04, -0.15))
    band = wall_band(dark, size)
    ratio = {}

    def blender(scene, size):
        return render_blender(scene, size, samples=SAMPLES, pool=pool)

    for name, draw in (("raster", render_raster), ("blender", blender)):
        before, after = (draw(scene, size).image.astype(np.float64).mean(axis=2) for scene in (bright, dark))
        ratio[name] = after[band].mean() / before[band].mean()
    assert ratio["raster"] < 0.93, ratio  # (1 - 0.15) / 1.04 in linear light: 0.910 display-encoded, 0.911 Blender
    assert abs(ratio["blender"] - ratio["raster"]) < 0.02, ratio


@needs_bpy
def test_the_walls_foot_below_the_floor_is_the_raster_renderers(pool):
    """``plate.floor_height_mm`` moves the walls' band and outlines as much in Blender (films at the foot's height,
    seen in 3D) as in the raster renderer (a parallax about the camera's axis): over the pixels the raster renderer
    changes, both change them alike, and Blender changes nothing elsewhere."""
    size = (480, 360)
    settings = {"plaques.negative_plate": 1.0, "camera.distance_mm": 180.0, "wells.emptied": 0.0, "post.jpeg": 0.0,
                "plate.top_edge_through_floor": 0.0, "plate.wall_band": 0.3, "plate.wall_slant": 0.0, "plate.wall_glints": 0.0}
    flat, lifted = (sample_scene(load_config("high", overrides=settings | {"plate.floor_height_mm": h}), 6)
                    for h in (0.0, 3.0))
    change = {}
    for name, draw in (("raster", render_raster), ("blender", lambda s, z: render_blender(s, z, samples=SAMPLES, pool=pool))):
        before, after = (draw(scene, size).image.astype(np.float64).mean(axis=2) for scene in (flat, lifted))
        change[name] = after - before
    moved = ndimage.binary_dilation(np.abs(change["raster"]) > 3.0, iterations=2)
    assert moved.sum() > 5000
    raster, blender = change["raster"][moved], change["blender"][moved]
    assert raster.mean() > 1.5, raster.mean()  # levels; 2.47 measured, 2.19 in Blender
    assert abs(blender.mean() - raster.mean()) < 0.25 * raster.mean()
    assert np.abs(blender).mean() == pytest.approx(np.abs(raster).mean(), rel=0.3)  # 10.3 and 12.7 measured
    assert np.abs(change["blender"][~moved]).mean() < 0.3


@needs_bpy
def test_the_veiled_floor_past_the_top_edge_is_the_raster_renderers(pool):
    """``plate.crescent_veil`` pales the floor past the walls' top edge as much in Blender (the floor material, from
    where the ray meets the top edge's plane) as in the raster renderer (a parallax about the camera's axis), channel
    by channel, and changes neither the floor within the opening nor the masks."""
    size = (480, 360)
    settings = {"plaques.negative_plate": 1.0, "camera.distance_mm": 180.0, "wells.emptied": 0.0, "post.jpeg": 0.0,
                "plate.top_edge_through_floor": 0.0, "plate.top_edge_blur_mm": 0.0}
    plain, veiled = (sample_scene(load_config("high", overrides=settings | {"plate.crescent_veil": share}), 6)
                     for share in (0.0, 0.15))
    past, pixel_mm = past_top_edge(veiled, size)
    crescent, opening = past > 3 * pixel_mm, past < -3 * pixel_mm
    assert crescent.sum() > 1000
    rise, still = {}, {}
    for name, draw in (("raster", render_raster), ("blender", lambda s, z: render_blender(s, z, samples=SAMPLES, pool=pool))):
        before, after = (draw(scene, size) for scene in (plain, veiled))
        assert np.array_equal(before.wells, after.wells)
        change = after.image.astype(np.float64) - before.image.astype(np.float64)
        rise[name], still[name] = change[crescent].mean(axis=0), np.abs(change[opening]).mean()
    # levels, mean over the crescent: (+4.8, +42.0, -3.9) measured in the raster renderer, (+4.7, +41.9, -3.9) in
    # Blender; green, the channel the violet stain absorbs most, rises most, blue falls toward CRESCENT_LIGHT
    assert rise["raster"][1] > 20.0, rise
    np.testing.assert_allclose(rise["blender"], rise["raster"], atol=0.2 * rise["raster"][1])
    assert still["raster"] < 0.3 and still["blender"] < 0.3, still


@needs_bpy
def test_the_walls_refracted_lines_are_the_raster_renderers(pool):
    """``plate.wall_lines`` and ``plate.wall_highlights`` draw thin dark lines and highlights across the band over
    each wall, wandering around the well, where the raster renderer draws them: Blender's films, two samples a
    pixel, are speckled where a line is thinner than a pixel, so the changes are compared blurred over 1.5 pixels;
    nothing changes away from the walls."""
    size = (480, 360)
    settings = {"plaques.negative_plate": 1.0, "camera.distance_mm": 180.0, "wells.emptied": 0.0, "post.jpeg": 0.0,
                "plate.top_edge_through_floor": 0.0, "plate.floor_height_mm": 2.0}
    plain, lined = (sample_scene(load_config("high", overrides=settings | {"plate.wall_lines": dark, "plate.wall_highlights": bright}), 6)
                    for dark, bright in ((0.0, 0.0), (1.0, 0.4)))
    band = wall_band(lined, size, margin_px=-3.0)
    change = {}
    for name, draw in (("raster", render_raster), ("blender", lambda s, z: render_blender(s, z, samples=SAMPLES, pool=pool))):
        before, after = (draw(scene, size).image.astype(np.float64).mean(axis=2) for scene in (plain, lined))
        change[name] = ndimage.gaussian_filter(after - before, 1.5)
        assert np.abs((after - before)[~band]).mean() < 0.2, name  # 0.06 measured, 0.11 in Blender
    raster, blender = change["raster"][band], change["blender"][band]
    assert raster.std() > 1.5, raster.std()  # levels; 2.45 measured, 3.96 in Blender (its speckle)
    assert np.corrcoef(raster, blender)[0, 1] > 0.6  # 0.73 measured


@needs_bpy
def test_the_walls_tint_is_the_raster_renderers(pool):
    """``plate.wall_stain`` tints the band over each wall by its well's stain as much in Blender (the band's film,
    its ink times the well's tint) as in the raster renderer, channel by channel."""
    size = (480, 360)
    settings = {"plaques.negative_plate": 1.0, "wells.emptied": 0.0, "post.jpeg": 0.0,
                "plate.top_edge_through_floor": 0.0}
    plain, tinted = (sample_scene(load_config("high", overrides=settings | {"plate.wall_stain": share}), 6)
                     for share in (0.0, 0.05))
    band = wall_band(tinted, size)
    ratio = {}
    for name, draw in (("raster", render_raster), ("blender", lambda s, z: render_blender(s, z, samples=SAMPLES, pool=pool))):
        before, after = (draw(scene, size).image[band].astype(np.float64).mean(axis=0) for scene in (plain, tinted))
        ratio[name] = after / before
    assert ratio["raster"][1] < 0.93 and ratio["raster"][2] > 0.97, ratio  # green darkens, blue hardly
    np.testing.assert_allclose(ratio["blender"], ratio["raster"], atol=0.015)


@needs_bpy
def test_the_walls_sheen_is_the_raster_renderers(pool):
    """``plate.wall_slant`` and ``plate.wall_glints`` change the band's light around each well in Blender (the rim
    material's Fourier series, about world angles) as in the raster renderer: the same change pixel by pixel over
    the bands, brighter on the side away from the camera's axis."""
    size = (480, 360)
    settings = {"plaques.negative_plate": 1.0, "wells.emptied": 0.0, "post.jpeg": 0.0,
                "plate.top_edge_through_floor": 0.0, "plate.floor_height_mm": 0.0}
    plain, sheened = (sample_scene(load_config("high", overrides=settings | {"plate.wall_slant": slant,
                                                                             "plate.wall_glints": glints}), 6)
                      for slant, glints in ((0.0, 0.0), (0.25, 0.15)))
    band = wall_band(sheened, size)
    change = {}
    for name, draw in (("raster", render_raster), ("blender", lambda s, z: render_blender(s, z, samples=SAMPLES, pool=pool))):
        before, after = (draw(scene, size).image.astype(np.float64).mean(axis=2) for scene in (plain, sheened))
        change[name] = (after - before)[band]
    assert change["raster"].std() > 8.0, change["raster"].std()  # levels: 20.5 measured, 20.0 in Blender
    assert np.corrcoef(change["raster"], change["blender"])[0, 1] > 0.9  # 0.999 measured
    assert abs(change["blender"].std() - change["raster"].std()) < 0.15 * change["raster"].std()
