"""The parameter catalogue: every scene parameter, defined once, in the section it belongs to.

Each parameter is a field of a :class:`Section` of :class:`SceneConfig`, declared with
:func:`~platesynth.scene.distributions.number`, :func:`~platesynth.scene.distributions.probability` or
:func:`~platesynth.scene.distributions.category`: its name, kind, unit, valid range, default and a one-line
description. Most parameters are drawn once per plate; those whose description starts with "each" are drawn
again for every well, plaque, scratch, speck or blot. :func:`parameter_table` reads them for
``platesynth scene catalogue`` and the docs; :mod:`platesynth.scene.sample` draws them (:meth:`Section.draw`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

from platesynth.scene.distributions import (
    Categorical,
    Dist,
    DistVector,
    category,
    check_value,
    draw_value,
    number,
    probability,
)


class Section(BaseModel):
    """A group of parameters; checks each against its valid range."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)

    @field_validator("*", mode="after")
    @classmethod
    def _within_range(cls, value: Any, info: ValidationInfo) -> Any:
        return check_value(value, cls.model_fields[info.field_name].json_schema_extra or {})

    def draw(self, name: str, rng: np.random.Generator) -> Any:
        """Draw the parameter ``name`` of this section with ``rng``.

        Returns
        -------
        float, int, str or bool
            See :func:`~platesynth.scene.distributions.draw_value`.
        """
        return draw_value(getattr(self, name), type(self).model_fields[name].json_schema_extra or {}, rng)


class PlateConfig(Section):
    """The plate."""

    format: Dist = number(12, 6, 96, "wells", "number of wells (use {choice: [...]} to mix formats)", True, (6, 12, 24, 96))
    transmittance: Dist = number([0.72, 0.85], 0.3, 1.0, "", "light passing the plastic between wells")
    tint: Dist = number([0.0, 0.04], 0.0, 0.3, "", "blue tint of the plastic (0 = neutral)")
    rim_darkness: Dist = number([0.25, 0.45], 0.0, 1.0, "", "darkness of the well-wall outlines")
    label_strength: Dist = number([0.35, 0.7], 0.0, 1.0, "", "contrast of the embossed labels and rings")
    top_edge_through_floor: Dist = number(0.0, 0.0, 1.0, "",
                                          "share of the walls' top-edge outlines seen through a well's floor from "
                                          "below (an arc across the monolayer where parallax puts the edge)")
    top_edge_blur_mm: Dist = number(0.0, 0.0, 2.0, "mm",
                                    "how far the outlines of the walls' top edge are smeared: the top edge lies a "
                                    "well's depth from the floors the camera focuses on, so it is out of focus")
    crescent_veil: Dist = number(0.0, 0.0, 0.3, "",
                                 "share of the light that reaches the camera around the stain where, seen from "
                                 "below, a well's floor lies past the walls' top edge (the light came through the "
                                 "wall, not the open top): a paler crescent on each well's side away from the "
                                 "camera's axis, bounded by the top edge's arc")
    wall_band: Dist = number(0.04, -0.3, 0.3, "", "how much brighter the plate looks over a well's wall, seen end-on, "
                             "than over the plastic around it (negative: darker)")
    floor_height_mm: Dist = number(0.0, 0.0, 5.0, "mm",
                                   "height of the wells' floors above the foot of their walls (the plate's bottom "
                                   "edge): seen from below the foot is nearer the camera than the floor, so parallax "
                                   "shifts the walls' band and outlines outward from the monolayer, widest on the "
                                   "side away from the camera's axis")
    wall_stain: Dist = number(0.0, 0.0, 0.2, "",
                              "share of its well's stain the band over a wall takes: light that passed the stained "
                              "floor and is refracted into the wall, seen end-on (a stain-tinted ring around each well)")
    labels_at_junction: float = probability(
        0.0, "chance the wells' labels sit in their circles where four wells meet, each circle with a rib to its well, "
        "as on the photos' 12-well plates (else a little nearer their well)")
    wall_slant: Dist = number(0.0, -0.5, 0.5, "",
                              "how much brighter the band over a well's wall is on its side away from the camera's "
                              "axis than on the other, relative (the wall's inside seen at a slant through the floor)")
    wall_lines: Dist = number(0.0, 0.0, 1.0, "",
                              "darkness of the thin lines a thick wall refracts across its band, wandering a little "
                              "around the well (relative to the walls' outlines)")
    wall_highlights: Dist = number(0.0, 0.0, 0.5, "",
                                   "brightness of the thin highlights between those lines, relative")
    wall_glints: Dist = number(0.0, 0.0, 0.5, "",
                               "sd of the band's uneven brightness around each well, relative (light refracted and "
                               "reflected by the thick wall: glints and shadows that change around the well)")


class CameraConfig(Section):
    """Camera pose relative to the plate."""

    from_below: float = probability(1.0, "chance the plate is photographed through its bottom (mirrored)")
    plate_fill: Dist = number([1.13, 1.21], 0.2, 1.5, "", "plate length as a fraction of the image width")
    rotation_deg: Dist = number({"normal": [0.0, 0.6]}, -10.0, 10.0, "deg", "in-plane rotation")
    tilt_deg: Dist = number([0.0, 2.0], 0.0, 15.0, "deg", "tilt of the plate away from the camera axis")
    offset: Dist = number({"normal": [0.0, 0.012]}, -0.2, 0.2, "image", "offset of the plate centre, per axis")
    distance_mm: Dist = number([300, 500], 100, 2000, "mm", "camera distance (sets the parallax of the walls)")
    defocus_px: Dist = number([0.0, 0.4], 0.0, 5.0, "px", "optical blur at 1024 px image width")


class BackgroundConfig(Section):
    """What lies around the plate."""

    kind: Categorical = category("lightbox", ("lightbox", "desk"), "a light box under the plate, or a desk")
    brightness: Dist = number([0.88, 1.0], 0.0, 1.0, "", "brightness of the light box panel or the desk")
    desk_gray: Dist = number([0.03, 0.2], 0.0, 1.0, "", "grey level of the desk (or what surrounds the light box)")
    texture: Dist = number([0.0, 0.05], 0.0, 0.5, "", "amplitude of the desk's surface texture")
    ruler: float = probability(0.0, "chance of a ruler along the light box's edges")
    panel_margin_x_mm: Dist = number([40, 120], -50, 300, "mm",
                                     "distance from the plate's side to the nearest side edge of the light panel")
    panel_margin_y_mm: Dist = number([-5, 3], -50, 300, "mm",
                                     "distance from the plate's top/bottom to the nearest edge of the light panel")
    panel_below: float = probability(0.85, "chance the nearest panel edge lies below the plate (else above)")
    panel_portrait: float = probability(0.7, "chance the light panel stands upright (portrait) rather than across")
    panel_left: float = probability(0.6, "chance the plate lies near the panel's left side edge (else its right)")
    frame_mm: Dist = number([0.0, 15.0], 0.0, 100.0, "mm", "width of the light box's frame around the panel")
    desk_warmth: Dist = number([-0.03, 0.06], -0.5, 0.5, "",
                               "warmth of the desk: red raised and blue lowered by this fraction of its grey")
    panel_shade: Dist = number(0.0, 0.0, 1.0, "",
                               "share of its light a well's floor loses at its rim nearest the light panel's edge, "
                               "for a well at that edge (a darker band at the bottom of the wells nearest it)")
    panel_shade_reach_mm: Dist = number(20.0, 1.0, 200.0, "mm",
                                        "how far from the panel's edge the shade reaches: a well's shade falls by e "
                                        "over this distance between its floor's rim and the edge")
    panel_shade_width_mm: Dist = number(6.0, 0.5, 20.0, "mm",
                                        "width of the shaded band inside a well, from its rim nearest the panel's edge")


class StainConfig(Section):
    """The stained cell monolayer."""

    hue_deg: Dist = number([246, 286], 0.0, 360.0, "deg", "stain hue (crystal violet 240-290, neutral red 345-360)")
    saturation: Dist = number([0.9, 1.0], 0.0, 1.0, "", "stain saturation at nominal density")
    value: Dist = number([0.9, 1.0], 0.0, 1.0, "", "stain value (brightness) at nominal density")
    density: Dist = number([0.9, 1.15], 0.0, 3.0, "", "plate-wide stain density relative to nominal")
    well_density_jitter: Dist = number([0.02, 0.08], 0.0, 0.5, "", "relative density change from well to well (sd)")
    unevenness: Dist = number([0.04, 0.12], 0.0, 1.0, "", "low-frequency density variation")
    unevenness_scale_mm: Dist = number([2.0, 6.0], 0.5, 30.0, "mm", "size of low-frequency blotches")
    unevenness_light: Dist = number(
        0.0, 0.0, 3.0, "", "how much the layer's low-frequency blotches (unevenness) also dim the light in every "
        "channel alike, per unit of their effect on the density: a denser patch of cells scatters light away as well "
        "as absorbing it, so the photos' saturated wells vary in blue about as much as in red")
    centre_gradient: Dist = number([0.0, 0.15], 0.0, 1.0, "", "extra density of the elongated dark centre")
    centre_elongation: Dist = number([1.0, 2.0], 1.0, 5.0, "", "aspect ratio of the dark centre")
    drying_detail: Dist = number([0.01, 0.04], 0.0, 1.0, "", "high-frequency drying texture")
    rim_clearing_mm: Dist = number([0.1, 0.6], 0.0, 5.0, "mm", "width of the paler band along the rim")
    translucency: Dist = number([0.0, 0.008], 0.0, 1.0, "", "fraction of light passing un-absorbed")
    rim_mottle: Dist = number(0.0, 0.0, 1.0, "", "how much paler the patches of a mottled band along the rim are")
    rim_mottle_mm: Dist = number(2.0, 0.1, 10.0, "mm", "width of the mottled band along the rim")
    rim_mottle_grain_mm: Dist = number(0.06, 0.02, 0.5, "mm", "cell of the noise whose upper half are the mottled "
                                       "band's paler patches: patches about three cells across (Brisbane's photos "
                                       "have flakes of 0.2-0.4 mm)")
    rim_mottle_side: Dist = number(
        0.0, 0.0, 1.0, "", "how one-sided the mottled band is: 0 even all around, 1 only on the side of each well that "
        "faces one direction of the plate (drawn per plate: the side toward which the plate was tilted to empty it)")
    rim_mottle_angle_deg: Dist = number(
        [0.0, 360.0], 0.0, 360.0, "deg", "direction of the side the plate was tilted to, where each well's mottled band "
        "is strongest and its dye pooled (rim_mottle_side, pooling), drawn per plate: plate x axis 0, y axis 90 (a "
        "plate photographed from below, as the raster camera frames it: 0 the image's left, 90 its bottom)")
    rim_mottle_patches: Dist = number(
        0.0, 0.0, 1.0, "", "how patchy the mottled band is along the rim: 0 the same all round, 1 in stretches of a few "
        "millimetres with about half the rim bare (sheets of cells that came loose here and there)")
    meniscus: Dist = number(0.0, 0.0, 5.0, "", "extra stain density, relative, in a thin dark line along the rim where "
                            "the meniscus of the stain left more dye")
    crowd_thinning: Dist = number(0.0, 0.0, 20.0, "",
                                  "how much the layer between the plaques of a crowded well thins: its density times "
                                  "exp(-crowd_thinning * the share of the well's floor its plaques cover), as the "
                                  "photos' crowded wells are paler, their green no longer crushed")
    pooling: Dist = number(0.0, 0.0, 1.0, "", "extra stain density, relative, where the dye pooled in each well toward "
                           "the side the plate was tilted to (rim_mottle_side's, drawn per plate): this times "
                           "the square of the distance toward that side over the radius, so most near that rim "
                           "(the photos' wells are darker on one side, the same for every well of a plate)")
    lysed_density: Dist = number(0.6, 0.0, 2.0, "", "density a lysed well keeps where its remnant is full, relative")
    lysed_residue: Dist = number(0.04, 0.0, 1.0, "", "share of the layer a lysed well keeps everywhere (a pale film)")
    lysed_strands: Dist = number(1.0, 0.0, 3.0, "", "strength of the network of strands a lysed well keeps")
    lysed_grain: Dist = number(0.0, 0.0, 3.0, "", "granular texture of what a lysed well keeps")
    lysed_speckle: Dist = number(
        0.0, 0.0, 3.0, "", "fine speckle of what a lysed well keeps: grains of stained debris about 0.15 mm across, "
        "where lysed_grain draws flakes of about half a millimetre")
    lysed_disc: Dist = number(
        0.0, 0.0, 1.0, "", "share of what a lysed well keeps that gathers in a denser central disc with a ragged "
        "edge, the rest thinning out around it: 0 a cloud over the whole well")
    lysed_disc_radius: Dist = number(0.6, 0.2, 0.9, "", "radius of that disc, share of the well's radius")
    lysed_rim_loss: Dist = number(
        0.7, 0.0, 1.0, "", "share of what a lysed well keeps that it loses more near the rim (fading inward over "
        "render.appearance.LYSED_RIM_MM): 0.7 a clear ring between the film and the wall; 0 the film reaching the "
        "wall, as on the photos' blank IBV wells")
    lysed_clumps: Dist = number(
        0.0, 0.0, 0.3, "", "share of a lysed well's area still holding clumps of intact cells: dense, dark islands of "
        "the plate's stain, a fraction of a millimetre to about two across, amid the pale film")
    lysed_foam: Dist = number(
        0.0, 0.0, 1.0, "", "how fully round holes clear what a lysed well keeps: a foam of merged clearings with thin "
        "walls of stain between them, as on the blank wells of the photos (0: none; 1: the holes bare)")
    lysed_foam_mm: Dist = number(0.5, 0.1, 3.0, "mm", "median radius of the foam's holes")
    lysed_paleness: Dist = number(
        0.0, 0.0, 1.0, "", "how far the colour of what a lysed well keeps moves from the plate's stain toward a pale, "
        "bluish one drawn from pale_hue_deg and pale_saturation (a thin film of damaged cells): 0 the plate's, 1 the pale")
    lysed_haze: Dist = number(
        0.0, 0.0, 5.0, "", "absorbance in every channel alike that what a lysed well keeps adds per unit of its "
        "density, beside its colour's: dead cells and debris scatter light away, so the photos' blank Brisbane and "
        "PR8 wells are a darker, greyer mauve than a thin film of the stain (their blue 170-195 in 8-bit, not 205-230)")
    centre_gradient_factor: Dist = number([0.5, 1.0], 0.0, 2.0, "", "each well's factor on centre_gradient")
    centre_offset: Dist = number(0.15, 0.0, 1.0, "",
                                 "sd of a dark centre's offset from the well centre, per axis, fraction of its radius")
    drying_detail_factor: Dist = number([0.7, 1.0], 0.0, 2.0, "", "each well's factor on drying_detail")
    pale_plates: float = probability(
        0.0, "share of plates stained pale and bluish (a thin film, as on the IBV plates): their hue and saturation "
        "are drawn from pale_hue_deg and pale_saturation instead")
    pale_hue_deg: Dist = number([236.0, 248.0], 0.0, 360.0, "deg", "stain hue of a pale plate")
    pale_saturation: Dist = number([0.45, 0.7], 0.0, 1.0, "", "stain saturation of a pale plate at nominal density")


class WellsConfig(Section):
    """Which wells hold what."""

    emptied: float = probability(0.01, "chance a well holds no cells (clear), so no fixed pattern is learned")


class PlaquesConfig(Section):
    """Plaque counts (a dilution series across columns), sizes and shapes."""

    negative_plate: float = probability(0.5, "chance the plate holds no plaque at all")
    top_count: Dist = number({"loguniform": [20, 3000]}, 0, 100000, "plaques", "mean count in the least diluted column")
    dilution_factor: Dist = number({"choice": [10, 5, 3], "weights": [0.7, 0.2, 0.1]}, 1.0, 100.0, "",
                                   "dilution from one column to the next")
    reverse_series: float = probability(0.0, "chance the series runs from the last column to the first")
    lysis_count: Dist = number([90, 130], 1, 100000, "plaques",
                               "mean count above which a well is lysed (a person calls it uncountable)")
    lysed_lace: float = probability(
        0.0, "chance a lysed well is drawn as a lace of merged plaques, each in the plaque masks, over its damaged "
        "layer (stain.lysed_density, in the lysed colour; a person still calls it uncountable), instead of a pale film")
    lace_coverage: Dist = number([1.5, 2.5], 0.2, 5.0, "", "sum of the discs of a lace well's plaques, share of the "
                                 "well's area (2: about a seventh of the layer left, a network between merged holes)")
    radius_mm: Dist = number({"loguniform": [0.35, 1.5]}, 0.05, 10.0, "mm", "median plaque radius of the plate")
    radius_spread: Dist = number([0.2, 0.45], 0.0, 2.0, "", "sd of log radius within the plate")
    irregularity: Dist = number([0.02, 0.08], 0.0, 0.5, "", "amplitude of the outline's Fourier harmonics")
    softness: Dist = number([0.2, 0.45], 0.0, 2.0, "", "width of the fuzzy edge, fraction of the radius")
    clearness: Dist = number([0.95, 1.0], 0.0, 1.0, "", "fraction of stain removed inside a plaque")
    edge_bias: Dist = number([0.0, 0.3], 0.0, 1.0, "", "tendency of plaques to lie near the well's rim")
    max_overlap: Dist = number(1.0, 0.0, 1.0, "", "largest overlap of two plaques, fraction of the smaller radius")
    max_coverage: Dist = number(100.0, 0.05, 100.0, "",
                                "largest share of a well's area its plaques cover together (sum of their discs); "
                                "a crowded well's plaques shrink to fit, as plaques do that compete for cells "
                                "(the default, 100, never binds)")
    count_jitter: Dist = number(0.15, 0.0, 3.0, "",
                                "sd of the log of a well's mean count around the dilution series (pipetting error)")
    max_radius: Dist = number(0.5, 0.05, 1.0, "", "largest plaque radius, fraction of the well's radius")
    harmonic_decay: Dist = number(1.2, 0.0, 4.0, "",
                                  "fall-off of the outline harmonics: amplitude of order k is irregularity / k^decay")
    softness_factor: Dist = number([0.8, 1.25], 0.0, 5.0, "", "each plaque's factor on softness")
    clearness_factor: Dist = number([0.9, 1.1], 0.0, 5.0, "", "each plaque's factor on clearness (capped at 1)")
    fray: Dist = number(0.2, 0.0, 1.0, "", "how much radial fibres shift a plaque's edge (0: a smooth soft disc)")
    lumps: Dist = number(0.0, 0.0, 0.3, "", "how far lumps of about a tenth of a millimetre move a plaque's outline out "
                         "or in, share of its radius (crenellated, cauliflower-like edges; the plaque masks follow "
                         "them; 0: the smooth Fourier outline)")
    centre_residual: Dist = number(0.02, 0.0, 0.9, "", "share of the clearing a plaque's centre lacks (paler centre)")
    residual_mottle: Dist = number(0.03, 0.0, 0.3, "", "unevenness of the stain left inside a plaque: sd of the share "
                                   "left, in patches of about a tenth of a millimetre (0.03: a nearly even clearing; "
                                   "0.1-0.2: the mottled lilac inside the photos' large plaques)")
    residual_tint: Dist = number(0.0, 0.0, 1.0, "", "share of the stain left inside a plaque that takes the colour of "
                                 "what a lysed well keeps (stain.lysed_paleness: a paler, greyer, bluer lilac than the "
                                 "intact layer's; 0: the layer's colour)")
    edge_floor_mm: Dist = number(0.0, 0.0, 1.0, "mm", "narrowest fuzzy edge of a plaque: a small plaque's edge keeps "
                                 "at least this width, where softness times its radius is narrower (the photos' small "
                                 "plaques are blurred spots, not crisp dots; 0: softness times the radius alone)")
    halo: Dist = number(0.0, 0.0, 1.0, "", "clearing of the soft halo just outside a plaque's outline")
    halo_width: Dist = number(0.5, 0.01, 3.0, "", "reach of the halo beyond the outline, fraction of the radius")
    rim: Dist = number(0.0, 0.0, 3.0, "", "extra stain density along a plaque's outline (a thin darker rim)")
    edge_grain: Dist = number(0.0, 0.0, 1.0, "", "share of the clearing that clumps of cells not yet lysed keep in a ring "
                              "inside a plaque's outline: the photos' cottony plaques, granular toward a well-defined "
                              "edge and clearer in the middle (0: an even clearing; the plaque masks do not change)")
    edge_grain_width: Dist = number(0.3, 0.02, 1.0, "", "depth of the granular ring inside a plaque's outline, "
                                    "fraction of the radius (the clumps thin out over it toward the centre)")


class ArtifactsConfig(Section):
    """Scratches, marker writing, blots and debris."""

    pipette_scratch: float = probability(0.85, "chance of a pipette scratch near the top of a well")
    scratch_length_mm: Dist = number([0.8, 2.5], 0.0, 20.0, "mm", "length of a pipette scratch")
    scratch_width_mm: Dist = number([0.2, 0.4], 0.01, 3.0, "mm", "width of a scratch")
    pipette_length_factor: Dist = number([0.6, 1.3], 0.0, 5.0, "", "each pipette scratch's factor on scratch_length_mm")
    pipette_width_factor: Dist = number([0.8, 1.2], 0.0, 5.0, "", "each pipette scratch's factor on scratch_width_mm")
    pipette_bend: Dist = number({"normal": [0.0, 0.35]}, -5.0, 5.0, "",
                                "each pipette scratch's sideways bend at its end (a hook), fraction of its length")
    pipette_tilt_deg: Dist = number(0.0, -60.0, 60.0, "deg",
                                    "each pipette scratch's direction off the well's radius (drawn per scratch)")
    pipette_inset_mm: Dist = number(0.0, 0.0, 3.0, "mm",
                                    "how far inside the rim each pipette scratch starts (drawn per scratch)")
    extra_scratches: Dist = number([0.0, 0.3], 0.0, 10.0, "per well", "mean number of other scratches per well")
    scratch_length_factor: Dist = number([0.3, 1.0], 0.0, 5.0, "", "each other scratch's factor on scratch_length_mm")
    scratch_width_factor: Dist = number([0.5, 1.0], 0.0, 5.0, "", "each other scratch's factor on scratch_width_mm")
    scratch_roughness: Dist = number(0.0, 0.0, 0.9, "", "how ragged the plate's scratches are: each edge's distance "
                                     "from the centre line varies along them, each edge on its own, by up to this "
                                     "share (0: smooth, even strokes)")
    scratch_clearing: Dist = number(0.95, 0.0, 1.0, "", "share of the stain the plate's scratches scrape off (the "
                                    "photos' scrapes keep a pale violet-grey, not white)")
    scratch_softness_mm: Dist = number(0.0, 0.0, 1.0, "mm", "width over which the edges of the plate's scratches fade "
                                       "(torn cells, not a cut: 0 is as sharp as a pixel)")
    scratch_haze: Dist = number(0.0, 0.0, 0.9, "", "share of the light the scratched plastic under the plate's "
                                "scratches scatters away (a greyer scrape) where they scraped an intact layer (the "
                                "photos' lysed wells show no grey scrape on their pale film)")
    scratch_heaps: Dist = number(0.0, 0.0, 3.0, "", "extra stain density, relative, along the edges of the plate's "
                                 "scratches, where the cells they scraped off heaped up: thin dark margins (the photos' "
                                 "scrapes are white strips edged in dark lines; 0: none)")
    scratch_ridge: Dist = number(0.0, 0.0, 3.0, "", "extra stain density, relative, of the cells each of the plate's "
                                 "scratches rolled up: ragged flaps inside one of its edges (its side drawn per "
                                 "scratch) and a clump beside its end, dark on a white scrape (0: none)")
    rim_tears: Dist = number(0.0, 0.0, 5.0, "per well",
                             "mean number of tears per well: short, wide strips where the layer came off at the rim "
                             "(a pipette tip or the aspiration, anywhere around the well), drawn as the plate's "
                             "scratches are; pale lesions a counting model must not take for plaques")
    rim_tear_length_mm: Dist = number([1.0, 3.0], 0.1, 10.0, "mm", "each rim tear's length, from the rim at "
                                      "rim_tear_tilt_deg off the radius")
    rim_tear_width_mm: Dist = number([0.6, 1.5], 0.05, 5.0, "mm", "each rim tear's width")
    rim_tear_tilt_deg: Dist = number([0.0, 60.0], 0.0, 90.0, "deg",
                                     "each rim tear's angle off the well's radius, to either side (drawn per tear): "
                                     "0 straight inward, a bite; near 90 along the rim, a shallow crescent of bare "
                                     "plastic hugging it, as on the photos' torn wells")
    smears: Dist = number(0.0, 0.0, 5.0, "per well",
                          "mean number of dark smears per well: ragged bands where the layer folded or rolled up "
                          "or the stain clumped, denser than the layer around them, beside which the layer reads "
                          "paler (a counting model must not take that ground for plaques); none in a lysed well")
    smear_length_mm: Dist = number({"loguniform": [0.8, 7.0]}, 0.1, 20.0, "mm",
                                   "each smear's length along its centre line")
    smear_width_mm: Dist = number({"loguniform": [0.25, 1.5]}, 0.05, 5.0, "mm", "each smear's width")
    smear_darkness: Dist = number([0.8, 2.0], 0.0, 10.0, "", "each smear's added stain density, relative")
    marker: float = probability(0.6, "chance of marker writing on the plate")
    marker_strokes: Dist = number({"integers": [1, 3]}, 1, 20, "strokes", "number of pen strokes", integer=True)
    marker_size_mm: Dist = number([3.0, 7.0], 0.5, 40.0, "mm", "length of a pen stroke (strokes stand 0.6 of it apart)")
    marker_width_mm: Dist = number([0.35, 0.7], 0.05, 5.0, "mm", "width of the pen")
    marker_ink_rgb: DistVector = number([[0.0, 0.15], [0.2, 0.45], [0.5, 0.85]], 0.0, 1.0, "RGB",
                                        "ink colour, one value per channel (R, G, B)", size=3)
    blots: Dist = number([0.0, 1.0], 0.0, 20.0, "per plate", "mean number of stains/smudges on the plate")
    blot_radius_mm: Dist = number([0.5, 4.0], 0.05, 50.0, "mm", "each blot's radius")
    blot_rgb: DistVector = number([[0.3, 0.7], [0.2, 0.6], [0.3, 0.8]], 0.0, 1.0, "RGB",
                                  "each blot's colour, one value per channel (R, G, B)", size=3)
    blot_opacity: Dist = number([0.05, 0.3], 0.0, 1.0, "", "each blot's opacity at its centre")
    debris: Dist = number([0.0, 6.0], 0.0, 200.0, "per well", "mean number of dark specks per well")
    debris_length_mm: Dist = number([0.08, 0.5], 0.01, 10.0, "mm", "each speck's length")
    debris_width_factor: Dist = number([0.2, 0.7], 0.01, 1.0, "", "each speck's width, fraction of its length")
    debris_darkness: Dist = number([0.5, 2.5], 0.0, 10.0, "", "each speck's added stain density")


class LightingConfig(Section):
    """Light and exposure."""

    exposure_ev: Dist = number([-0.55, -0.1], -3.0, 3.0, "EV", "exposure correction")
    color_temperature_k: Dist = number([9000, 13000], 2500, 15000, "K",
                                       "colour temperature the camera's white balance leaves (higher: bluer)")
    vignetting: Dist = number([0.0, 0.15], 0.0, 1.0, "", "darkening at the image corners")
    glare: Dist = number([0.0, 0.04], 0.0, 1.0, "", "strength of a soft glare spot")
    glare_position: DistVector = number([[0.0, 1.0], [0.0, 1.0]], 0.0, 1.0, "image",
                                        "centre of the glare spot, image fractions (x, y)", size=2)
    glare_radius: Dist = number([0.1, 0.4], 0.01, 2.0, "", "radius of the glare spot, fraction of the image diagonal")


class PostConfig(Section):
    """Post-processing: each effect is switched on with a probability and drawn with a strength."""

    brightness: float = probability(0.5, "chance of a brightness change")
    brightness_strength: Dist = number([-0.08, 0.08], -1.0, 1.0, "", "brightness change")
    white_balance: float = probability(0.5, "chance of a colour cast")
    white_balance_strength: Dist = number([0.0, 0.05], 0.0, 1.0, "", "size of the colour cast")
    clarity: float = probability(0.4, "chance of a local contrast change")
    clarity_strength: Dist = number([-0.2, 0.3], -1.0, 1.0, "", "local contrast change")
    motion_blur: float = probability(0.1, "chance of motion blur")
    motion_blur_strength: Dist = number([0.5, 2.0], 0.0, 30.0, "px", "motion blur length at 1024 px width")
    shadows: float = probability(0.3, "chance of low-frequency shadows")
    shadows_strength: Dist = number([0.02, 0.08], 0.0, 1.0, "", "depth of the shadows")
    chromatic_aberration: float = probability(0.3, "chance of chromatic aberration")
    chromatic_aberration_strength: Dist = number([0.3, 1.2], 0.0, 10.0, "px", "colour shift at the corners")
    bloom: float = probability(0.3, "chance of bloom")
    bloom_strength: Dist = number([0.05, 0.2], 0.0, 1.0, "", "glow around bright areas")
    sharpen: float = probability(1.0, "chance of sharpening")
    sharpen_strength: Dist = number([1.0, 2.0], 0.0, 2.0, "", "unsharp-mask amount")
    sharpen_luma: Dist = number(0.0, 0.0, 1.0, "", "share of the sharpening done on the luminance alone, as a "
                                "phone does (0 sharpens each colour channel: coloured halos at coloured edges)")
    sharpen_threshold: Dist = number(0.0, 0.0, 20.0, "levels", "detail the sharpening leaves alone, in 8-bit levels: "
                                     "only the part of a pixel's detail beyond it is sharpened (coring, as a phone "
                                     "sharpens edges but not the flat stain's grain; 0 sharpens everything)")
    noise: float = probability(1.0, "chance of sensor noise")
    noise_strength: Dist = number([1.0, 2.5], 0.0, 30.0, "levels", "noise sd in 8-bit levels")
    noise_grain_px: Dist = number(0.0, 0.0, 3.0, "px", "sd of the blur that clumps the noise into grains, px at 1024 px "
                                  "width, its sd kept (a phone's demosaicing and denoising; 0: each pixel its own)")
    black_level: Dist = number(0.0, 0.0, 0.2, "", "display level (0..1) a phone's tone curve maps to black, after the "
                               "noise: darker levels clip to 0 and the rest is stretched to keep white (the photos' "
                               "saturated wells have their green at 0)")
    jpeg: float = probability(0.9, "chance of JPEG compression")
    jpeg_strength: Dist = number([0.05, 0.2], 0.0, 0.9, "", "1 - JPEG quality/100")


class SceneConfig(BaseModel):
    """Ranges and distributions of every scene parameter; :func:`platesynth.scene.sample_scene` draws a Scene."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = Field(default="custom", description="name of the configuration (the preset's name)")
    plate: PlateConfig = PlateConfig()
    camera: CameraConfig = CameraConfig()
    background: BackgroundConfig = BackgroundConfig()
    stain: StainConfig = StainConfig()
    wells: WellsConfig = WellsConfig()
    plaques: PlaquesConfig = PlaquesConfig()
    artifacts: ArtifactsConfig = ArtifactsConfig()
    lighting: LightingConfig = LightingConfig()
    post: PostConfig = PostConfig()


def sections() -> dict[str, type[Section]]:
    """The sections of :class:`SceneConfig` by name, in order."""
    return {
        name: field.annotation
        for name, field in SceneConfig.model_fields.items()
        if isinstance(field.annotation, type) and issubclass(field.annotation, Section)
    }


def parameter_names() -> list[str]:
    """Every parameter's dotted name, e.g. ``plaques.radius_mm``."""
    return [f"{s}.{p}" for s, model in sections().items() for p in model.model_fields]


def parameter_table() -> list[dict[str, Any]]:
    """One row per parameter: name, type, unit, range, default and description (read from the fields).

    Returns
    -------
    list of dict
        Keys ``name``, ``type``, ``unit``, ``range`` (``[low, high]`` or the list of options), ``default``
        (in the form a YAML file takes), ``description``.
    """
    rows = []
    for section, model in sections().items():
        for name, field in model.model_fields.items():
            extra = field.json_schema_extra or {}
            default = field.default
            rows.append(
                {
                    "name": f"{section}.{name}",
                    "type": extra["kind"],
                    "unit": extra.get("unit", ""),
                    "range": list(extra.get("options") or extra.get("choices") or extra["bounds"]),
                    "default": default.model_dump() if isinstance(default, BaseModel) else default,
                    "description": field.description,
                }
            )
    return rows

