"""The concrete scene: every number a renderer needs to draw one image, and nothing random.

Units and conventions (shared by the raster and the Blender renderer):

* Plate coordinates are millimetres on the plate's bottom plane, seen **from above**, with the origin at the
  plate's top-left corner (the A1 corner), ``x`` to the right (increasing column number) and ``y`` down
  (increasing row letter). SBS footprint: 127.76 x 85.48 mm.
* Angles are degrees; colours are RGB floats in [0, 1] (linear), stain colours also as HSV floats.
* A photograph from below mirrors the plate left-right in the image (``camera.from_below``).
* Image-grid positions (``Well.row``/``Well.col``) count from the image's top-left; well ids in the well mask
  are ``row * n_cols + col + 1`` in that grid.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from platesynth.errors import ParameterError

SCENE_VERSION = 1

Vec2 = tuple[float, float]
RGB = tuple[float, float, float]


class _Concrete(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class PlateGeometry(_Concrete):
    """SBS-standard plate geometry for one format."""

    format: Literal[6, 12, 24, 96] = Field(description="number of wells")
    rows: int = Field(description="well rows (letters A..)")
    cols: int = Field(description="well columns (numbers 1..)")
    length_mm: float = Field(127.76, description="plate length (x), mm")
    width_mm: float = Field(85.48, description="plate width (y), mm")
    height_mm: float = Field(20.0, description="plate height, mm")
    corner_radius_mm: float = Field(3.0, description="radius of the plate's rounded corners, mm")
    chamfer_mm: float = Field(4.0, description="size of the cut corner at A1 (top-left seen from above), mm")
    skirt_mm: float = Field(3.0, description="width of the flange around the plate's base, mm")
    a1_x_mm: float = Field(description="x of the centre of well A1, mm")
    a1_y_mm: float = Field(description="y of the centre of well A1, mm")
    pitch_mm: float = Field(description="centre-to-centre distance of neighbouring wells, mm")
    well_radius_mm: float = Field(description="radius of a well's flat bottom (the cell monolayer), mm")
    wall_mm: float = Field(description="thickness of a well's wall, mm")
    well_depth_mm: float = Field(description="height of a well's wall above its bottom, mm")


class PlateLook(_Concrete):
    """The plate's plastic and markings."""

    transmittance: float = Field(description="light passing the plastic between wells, 0..1")
    tint_rgb: RGB = Field(description="colour of the plastic (multiplies transmitted light), RGB 0..1")
    rim_darkness: float = Field(description="darkness of the well-wall outlines, 0..1")
    label_strength: float = Field(description="contrast of the embossed labels and rings, 0..1")
    top_edge_through_floor: float = Field(
        0.0, description="share of the walls' top-edge outlines seen through a well's floor from below, 0..1")
    top_edge_blur_mm: float = Field(0.0, description="width over which the top edge's outlines are smeared, mm")
    crescent_veil: float = Field(
        0.0, description="share of the light reaching the camera around the stain where a floor lies past the walls' "
                         "top edge, seen from below, 0..1")
    wall_band: float = Field(
        0.04, description="relative brightness of the plate over a well's wall, seen end-on (negative: darker)")
    floor_height_mm: float = Field(
        0.0, description="height of the wells' floors above the foot of their walls, mm (parallax of the foot)")
    wall_stain: float = Field(0.0, description="share of its well's stain the band over a wall takes, 0..1")
    wall_slant: float = Field(
        0.0, description="how much brighter the band over a wall is on its side away from the camera's axis, relative")
    labels_at_junction: bool = Field(
        False, description="the wells' label circles sit where four wells meet, each with a rib to its well")
    wall_glints: float = Field(0.0, description="sd of the band's uneven brightness around each well, relative")
    wall_lines: float = Field(
        0.0, description="darkness of the thin lines a wall refracts across its band, relative to its outlines")
    wall_highlights: float = Field(0.0, description="brightness of the thin highlights between those lines, relative")


class Stain(_Concrete):
    """The stain and monolayer properties shared by the whole plate (crystal violet: purple-blue; neutral red: red)."""

    hue_deg: float = Field(description="hue of the monolayer at nominal density, degrees")
    saturation: float = Field(description="saturation at nominal density, 0..1")
    value: float = Field(description="value (brightness) at nominal density, 0..1")
    unevenness: float = Field(description="amplitude of low-frequency density variation, relative")
    unevenness_scale_mm: float = Field(description="size of the low-frequency blotches, mm")
    unevenness_light: float = Field(0.0, description="how much the blotches also dim the light in every channel "
                                    "alike, per unit of their effect on the density")
    centre_elongation: float = Field(description="aspect ratio of the wells' dark centres (1 = round)")
    rim_clearing_mm: float = Field(description="width of the thinner, paler band along the rim, mm")
    translucency: float = Field(description="fraction of light passing un-absorbed (gaps in the layer), 0..1")
    rim_mottle: float = Field(0.0, description="how much paler the patches of the mottled band along the rim are, 0..1")
    rim_mottle_mm: float = Field(2.0, description="width of the mottled band along the rim, mm")
    rim_mottle_grain_mm: float = Field(0.06, description="cell of the noise of the mottled band's patches, mm")
    rim_mottle_side: float = Field(0.0, description="how one-sided the mottled band is, 0 (all around) to 1")
    rim_mottle_patches: float = Field(0.0, description="how patchy the mottled band is along the rim, 0 (even) to 1")
    rim_mottle_angle_deg: float = Field(0.0, description="direction of the side the plate was tilted to, where the "
                                        "band is strongest and the dye pooled, degrees (plate x axis 0, y axis 90)")
    meniscus: float = Field(0.0, description="extra stain density in a thin line along the rim, relative")
    crowd_thinning: float = Field(0.0, description="how much the layer between a crowded well's plaques thins: its "
                                  "density times exp(-crowd_thinning * the share of the floor its plaques cover)")
    pooling: float = Field(0.0, description="extra stain density, relative, where the dye pooled toward the side of "
                                            "rim_mottle_angle_deg: this times the square of the distance toward it "
                                            "over the radius")
    lysed_density: float = Field(0.6, description="density a lysed well keeps where its remnant is full, relative")
    lysed_residue: float = Field(0.04, description="share of the layer a lysed well keeps everywhere (a pale film)")
    lysed_strands: float = Field(1.0, description="strength of the network of strands a lysed well keeps")
    lysed_grain: float = Field(0.0, description="granular texture of what a lysed well keeps (relative, per sd)")
    lysed_speckle: float = Field(0.0, description="fine speckle of what a lysed well keeps (relative, per sd)")
    lysed_disc: float = Field(0.0, description="share of what a lysed well keeps gathered in a central disc, 0..1")
    lysed_disc_radius: float = Field(0.6, description="radius of that disc, share of the well's radius")
    lysed_rim_loss: float = Field(0.7, description="share of what a lysed well keeps that it loses more near the "
                                  "rim, 0..1")
    lysed_clumps: float = Field(0.0, description="share of a lysed well's area still holding clumps of intact cells")
    lysed_foam: float = Field(0.0, description="how fully a foam of round holes clears what a lysed well keeps, 0..1")
    lysed_foam_mm: float = Field(0.5, description="median radius of the foam's holes, mm")
    lysed_paleness: float = Field(
        0.0, description="how far the colour of what a lysed well keeps moves from the plate's toward the pale one, 0..1")
    lysed_haze: float = Field(0.0, description="absorbance in every channel alike that what a lysed well keeps "
                              "adds per unit of its density (light its debris scatters away)")
    lysed_hue_deg: float | None = Field(None, description="hue of the pale colour of what a lysed well keeps, degrees")
    lysed_saturation: float | None = Field(None, description="saturation of that pale colour at nominal density, 0..1")

    @model_validator(mode="after")
    def _pale_lysed_colour_is_given(self) -> Stain:
        if self.lysed_paleness > 0.0 and (self.lysed_hue_deg is None or self.lysed_saturation is None):
            raise ValueError("lysed_paleness > 0 needs lysed_hue_deg and lysed_saturation")
        return self


class WellStain(_Concrete):
    """How the monolayer of one well differs from the plate's."""

    density: float = Field(description="stain density relative to the plate's nominal colour (1 = nominal)")
    centre_gradient: float = Field(description="extra density of the elongated dark centre, relative")
    centre_angle_deg: float = Field(description="orientation of the dark centre's long axis, degrees")
    centre_offset_mm: Vec2 = Field(description="offset of the dark centre from the well centre, mm")
    drying_detail: float = Field(description="amplitude of high-frequency drying texture, relative")


class Well(_Concrete):
    """One well of the plate."""

    id: int = Field(description="value in the well mask (1..n), row-major in the image grid")
    row: int = Field(description="row in the image grid, 0-based from the top")
    col: int = Field(description="column in the image grid, 0-based from the left")
    label: str = Field(description="the plate's embossed name, e.g. 'A1'")
    center_mm: Vec2 = Field(description="centre in plate coordinates, mm")
    emptied: bool = Field(description="holds no cells (clear plastic)")
    lysed: bool = Field(description="confluent lysis: the layer is mostly gone, no countable plaques")
    lace: bool = Field(False, description="a lysed well drawn as a lace of merged plaques (in the plaque masks) over "
                       "its damaged layer instead of a pale film")
    expected_plaques: float = Field(description="mean plaque count of the dilution for this well")
    stain: WellStain

    @property
    def countable(self) -> bool:
        """Whether a person would count this well's plaques (not a lysed or emptied well)."""
        return not (self.lysed or self.emptied)

    @property
    def lysed_film(self) -> bool:
        """Whether the layer is drawn as the pale film a lysed well keeps: lysed, and not a lace."""
        return self.lysed and not self.lace


class Plaque(_Concrete):
    """One plaque: a clear, fuzzy-edged lesion in the monolayer.

    Its outline is ``r(t) = radius_mm * (1 + sum_k a_k cos(k t) + b_k sin(k t))`` for ``k = 2, 3, ...`` with
    ``t`` the angle around ``center_mm`` in plate coordinates; ``fourier`` holds the pairs ``(a_k, b_k)``.
    Later plaques lie on top of earlier ones.
    """

    id: int = Field(description="1..m in drawing order")
    well: int = Field(description="id of the well holding it")
    center_mm: Vec2 = Field(description="centre in plate coordinates, mm")
    radius_mm: float = Field(description="mean radius, mm")
    fourier: tuple[Vec2, ...] = Field(description="outline coefficients (a_k, b_k) for k = 2, 3, ...")
    softness: float = Field(description="width of the fuzzy edge as a fraction of the radius")
    clearness: float = Field(description="fraction of the stain removed inside, 0..1")


class PlaqueLook(_Concrete):
    """How the plate's plaques look (the defaults are the first model's look: frayed, fully cleared discs)."""

    fray: float = Field(0.2, description="how much radial fibres shift a plaque's edge, share of the edge's ramp")
    lumps: float = Field(0.0, description="how far lumps move a plaque's outline out or in, share of its radius per sd "
                         "of the noise (crenellated, cauliflower-like edges)")
    centre_residual: float = Field(0.02, description="share of the clearing a plaque's centre lacks (a paler, "
                                   "translucent centre)")
    residual_mottle: float = Field(0.03, description="sd of the share of stain left inside a plaque, in patches of "
                                   "about a tenth of a millimetre")
    residual_tint: float = Field(0.0, description="share of the stain left inside a plaque in the colour of what a "
                                 "lysed well keeps")
    edge_floor_mm: float = Field(0.0, description="narrowest fuzzy edge of any plaque, mm (a plaque's edge is the "
                                 "wider of this and its softness times its radius)")
    halo: float = Field(0.0, description="clearing of the soft halo just outside a plaque's outline")
    halo_width: float = Field(0.5, description="reach of the halo beyond the outline, share of the radius")
    rim: float = Field(0.0, description="extra stain density on a thin band along a plaque's outline (a darker rim)")
    edge_grain: float = Field(0.0, description="share of the clearing that clumps of cells not yet lysed keep in a "
                              "ring inside a plaque's outline (a granular edge)")
    edge_grain_width: float = Field(0.3, description="depth of that ring inside the outline, share of the radius")


class Scratch(_Concrete):
    """A pipette scratch: a curved streak where the cells were scraped off."""

    well: int = Field(description="id of the well holding it")
    points_mm: tuple[Vec2, ...] = Field(description="polyline in plate coordinates, mm")
    width_mm: float = Field(description="width, mm")
    ridge_side: int = Field(1, description="the side of its centre line where the cells it scraped off heaped up "
                                           "(+1 left, -1 right, looking along it; ``Artifacts.scratch_ridge``)")


class MarkerStroke(_Concrete):
    """A stroke of marker pen on the plate (hand-writing)."""

    points_mm: tuple[Vec2, ...] = Field(description="polyline in plate coordinates, mm")
    width_mm: float = Field(description="pen width, mm")
    color_rgb: RGB = Field(description="ink colour, RGB 0..1")


class Blot(_Concrete):
    """A stain or smudge on the plate or in a well."""

    center_mm: Vec2 = Field(description="centre in plate coordinates, mm")
    radius_mm: float = Field(description="radius, mm")
    color_rgb: RGB = Field(description="colour, RGB 0..1")
    opacity: float = Field(description="opacity at the centre, 0..1")


class Debris(_Concrete):
    """A dark speck (dust, precipitated stain) inside a well."""

    well: int = Field(description="id of the well holding it")
    center_mm: Vec2 = Field(description="centre in plate coordinates, mm")
    length_mm: float = Field(description="length, mm")
    width_mm: float = Field(description="width, mm")
    angle_deg: float = Field(description="orientation, degrees")
    darkness: float = Field(description="added stain density, relative")


class Smear(_Concrete):
    """A dark, ragged band inside a well where the layer folded or rolled up, or the stain clumped."""

    well: int = Field(description="id of the well holding it")
    points_mm: tuple[Vec2, ...] = Field(description="its centre line, a polyline in plate coordinates, mm")
    width_mm: float = Field(description="width, mm")
    darkness: float = Field(description="added stain density, relative")


class Artifacts(_Concrete):
    """Everything on the plate that is not the assay itself."""

    scratches: tuple[Scratch, ...] = ()
    scratch_roughness: float = Field(0.0, description="share by which the scratches' width varies along them")
    scratch_clearing: float = Field(0.95, description="share of the stain the scratches scrape off, 0..1")
    scratch_softness_mm: float = Field(0.0, description="width over which the scratches' edges fade, mm")
    scratch_haze: float = Field(0.0, description="share of the light the scratched plastic scatters away, 0..1")
    scratch_heaps: float = Field(0.0, description="added stain density, relative, along the scratches' edges")
    scratch_ridge: float = Field(0.0, description="added stain density, relative, of the flaps of cells rolled up "
                                                  "inside one edge of each scratch and the clump beside its end")
    marker: tuple[MarkerStroke, ...] = ()
    blots: tuple[Blot, ...] = ()
    debris: tuple[Debris, ...] = ()
    smears: tuple[Smear, ...] = ()


class Background(_Concrete):
    """What lies around and under the plate."""

    kind: Literal["lightbox", "desk"] = Field(description="a light box under the plate, or a desk")
    brightness: float = Field(description="brightness of the light box panel or the desk, 0..1")
    color_rgb: RGB = Field(description="colour of the desk or of the light box's frame, RGB 0..1")
    texture: float = Field(description="amplitude of the surface texture, relative")
    ruler: bool = Field(description="an L-shaped ruler lies along the light panel's left and bottom edges")
    panel_mm: tuple[float, float, float, float] = Field(
        description="glowing panel of the light box (left, top, right, bottom): mm from the plate centre along the "
        "image's x and y (before the camera's rotation)"
    )
    frame_mm: float = Field(description="width of the light box's frame around the panel, mm")
    panel_shade: float = Field(0.0, description="share of its light a well's floor loses at its rim nearest the "
                               "light panel's edge, for a well at that edge")
    panel_shade_reach_mm: float = Field(20.0, description="distance between a floor's rim and the panel's edge over "
                                        "which the shade falls by e, mm")
    panel_shade_width_mm: float = Field(6.0, description="width of the shaded band inside a well, from its rim "
                                        "nearest the panel's edge, mm")


class Lighting(_Concrete):
    """Light and exposure."""

    exposure_ev: float = Field(description="exposure correction, EV (stops)")
    color_temperature_k: float = Field(description="colour temperature of the light, kelvin")
    vignetting: float = Field(description="darkening at the image corners, 0..1")
    glare_strength: float = Field(description="strength of a soft glare spot, 0..1")
    glare_center: Vec2 = Field(description="glare position as image fractions (x, y)")
    glare_radius: float = Field(description="glare radius as a fraction of the image diagonal")


class Camera(_Concrete):
    """Where the camera is."""

    from_below: bool = Field(description="photographed through the plate's bottom (mirrored image)")
    plate_fill: float = Field(description="plate length as a fraction of the image width")
    rotation_deg: float = Field(description="in-plane rotation, degrees")
    tilt_x_deg: float = Field(description="tilt about the image's horizontal axis, degrees")
    tilt_y_deg: float = Field(description="tilt about the image's vertical axis, degrees")
    offset: Vec2 = Field(description="plate centre offset from the image centre, image fractions (x, y)")
    distance_mm: float = Field(description="camera distance from the plate's bottom, mm (sets parallax of the walls)")
    defocus_px: float = Field(description="optical blur, pixels at 1024 px image width")


class Effect(_Concrete):
    """One post-processing effect: a switch and a strength."""

    enabled: bool = False
    strength: float = 0.0


class PostProcessing(_Concrete):
    """Photographic post-processing, applied in this order."""

    brightness: Effect = Field(default=Effect(), description="brightness change, strength in [-1, 1]")
    white_balance: Effect = Field(default=Effect(), description="colour cast, strength 0..1")
    white_balance_shift: RGB = Field(default=(1.0, 1.0, 1.0), description="per-channel gains of the cast")
    clarity: Effect = Field(default=Effect(), description="local contrast, strength in [-1, 1]")
    motion_blur: Effect = Field(default=Effect(), description="blur along a line, strength = length in px at 1024 px")
    motion_blur_angle_deg: float = Field(default=0.0, description="direction of the motion blur, degrees")
    shadows: Effect = Field(default=Effect(), description="low-frequency shadows, strength 0..1")
    chromatic_aberration: Effect = Field(default=Effect(), description="lateral colour shift, px at the corners")
    bloom: Effect = Field(default=Effect(), description="glow around bright areas, strength 0..1")
    sharpen: Effect = Field(default=Effect(), description="unsharp masking, strength 0..2")
    sharpen_luma: float = Field(default=0.0, description="share of the sharpening done on the luminance alone, 0..1")
    sharpen_threshold: float = Field(default=0.0, description="detail the sharpening leaves alone, 8-bit levels: only "
                                     "what exceeds it is sharpened (coring)")
    noise: Effect = Field(default=Effect(), description="sensor noise, standard deviation in 8-bit levels")
    noise_grain_px: float = Field(default=0.0, description="sd of the blur that clumps the noise, px at 1024 px width")
    black_level: float = Field(default=0.0, description="display level the tone curve maps to black, 0..1 (the rest "
                               "stretched to keep white)")
    jpeg: Effect = Field(default=Effect(), description="JPEG compression, strength = 1 - quality/100")


class Scene(_Concrete):
    """A concrete scene: what a renderer draws and what a dataset saves (``model_dump(mode="json")``)."""

    version: int = SCENE_VERSION
    seed: int = Field(description="seed of the renderer's textures and noise")
    plate: PlateGeometry
    plate_look: PlateLook
    stain: Stain
    wells: tuple[Well, ...]
    plaques: tuple[Plaque, ...]
    plaque_look: PlaqueLook = PlaqueLook()
    artifacts: Artifacts
    background: Background
    lighting: Lighting
    camera: Camera
    post: PostProcessing

    def well_by_id(self) -> dict[int, Well]:
        """Wells keyed by their mask id."""
        return {well.id: well for well in self.wells}


def load_scene(path: str | Path) -> Scene:
    """Read a scene saved as JSON (e.g. a dataset's ``params/*.json``).

    Raises
    ------
    ParameterError
        If the file is missing or does not hold a valid scene.
    """
    path = Path(path)
    if not path.is_file():
        raise ParameterError(f"{path}: no such scene file")
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ParameterError(f"{path}: not a JSON file ({exc})") from None
    if isinstance(data, dict) and "scene" in data and "plate" not in data:
        data = data["scene"]  # a dataset's params file: the scene and how it was rendered
    try:
        return Scene.model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(part) for part in first["loc"])
        raise ParameterError(f"{path}: not a valid scene ({where}: {first['msg']})") from None
