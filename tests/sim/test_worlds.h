#pragma once
// Small worlds shared by the sim tests.

#include <lookup/sim/scenario.h>

namespace lookup::sim::testing {

/// A straight 40 m tunnel along +x from the origin, no openings, niches, furniture or relief
/// (straight smooth walls); the rock texture stays unless `plain`.
inline WorldOptions straightTunnel(bool plain) {
    WorldOptions w;
    w.layout = "single";
    w.length_m = 40;
    w.bend_max_deg = 0;
    w.drawpoint_spacing_m = 0;
    w.junction_spacing_m = 0;
    w.bump_amplitude_m = 0;
    w.duct_radius_m = 0;
    w.pipe_radius_m = 0;
    w.cable_span_m = 0;
    w.light_spacing_m = 0;
    w.sign_spacing_m = 0;
    w.grid_resolution_m = 0.05;
    w.wall_roughness_m = 0;
    w.niche_spacing_m = 0;
    if (plain) {
        w.rock_contrast = 0;
        w.bolt_spacing_m = 0;
        w.mesh_fraction = 0;
        w.shotcrete_fraction = 0;
    }
    return w;
}

/// A short two-traverse scenario (a mapping and reference "middle", a query "zigzag") with
/// small images, quick enough for every CI run.
inline ScenarioOptions tinyScenario() {
    ScenarioOptions s;
    s.name = "tiny";
    s.seed = 11;
    s.world.length_m = 25;
    s.world.drawpoint_spacing_m = 12;
    s.world.grid_resolution_m = 0.1;
    s.ceiling_camera.width_px = 96;
    s.ceiling_camera.height_px = 72;
    s.forward_camera.width_px = 48;
    s.forward_camera.height_px = 36;
    TraverseOptions a;
    a.name = "middle";
    a.roles = "mapping,reference";
    a.speed_kmh = 25;
    TraverseOptions b = a;
    b.name = "zigzag";
    b.roles = "query";
    b.zigzag_amplitude_m = 1.0;
    b.zigzag_period_m = 10;
    s.traverses = {a, b};
    return s;
}

}  // namespace lookup::sim::testing
