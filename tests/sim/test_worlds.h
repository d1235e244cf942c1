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

}  // namespace lookup::sim::testing
