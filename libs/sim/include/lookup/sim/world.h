#pragma once
// The synthetic mine: a network of straight tunnel pieces (capsules in plan view) with an arched
// profile, a world-anchored ceiling texture and 3-D furniture below the ceiling. Every query is
// a pure function of the position and the seed.

#include "lookup/sim/scenario.h"

#include <mrpt/maps/COccupancyGridMap2D.h>
#include <Eigen/Core>

#include <cstdint>
#include <limits>
#include <vector>

namespace lookup::sim {

/// A straight piece of tunnel: in plan view the points within `half_width` of segment a-b.
struct TunnelSegment {
    Eigen::Vector2d a, b;   ///< centre-line end points in the map [m]
    Eigen::Vector2d dir;    ///< unit vector a -> b
    Eigen::Vector2d left;   ///< dir rotated +90 deg
    double length = 0;      ///< |b - a| [m]
    double half_width = 0;  ///< [m]
    double s0 = 0;          ///< texture coordinate along the tunnel at `a` [m]
    bool on_route = false;  ///< part of the drivable route (main tunnels and their crosscut)
};

/// Where a plan-view point lies relative to the tunnels.
struct WallQuery {
    double sdf = 1e9;  ///< signed distance to the nearest wall: < 0 inside a tunnel [m]
    int segment = -1;  ///< nearest tunnel piece (-1: none near)
    double s = 0;      ///< texture coordinate along that piece [m]
    double d = 0;      ///< lateral offset from its centre line, + left [m]
    /// Wall relief included in sdf (sdf = distance to the smooth wall - relief) [m]; in the
    /// tunnel's interior, where the relief is not evaluated, -wall_roughness_m (its bound).
    double relief = 0;
};

enum class SurfaceKind { None, Roof, Wall, Floor, Duct, Pipe, Cable, Light };

/// A finite cylinder (ducts, pipes, cable pieces).
struct Cylinder {
    Eigen::Vector3d a, axis;  ///< start point and unit axis
    double length = 0, radius = 0;
    SurfaceKind kind = SurfaceKind::Duct;
    Eigen::Vector3d lo, hi;  ///< bounding box
};

/// A tunnel light: a self-luminous sphere.
struct Lamp {
    Eigen::Vector3d centre;
    double radius = 0.12;
};

/// A bright disc painted on the ceiling (used by tests to check the camera model).
struct CeilingMarker {
    double x = 0, y = 0, radius = 0.05, albedo = 4.0;
};

/// A first intersection of a ray with the static tunnel surfaces.
struct SurfaceHit {
    double t = std::numeric_limits<double>::infinity();  ///< ray parameter (|d| = 1: metres)
    SurfaceKind kind = SurfaceKind::None;
    WallQuery q;  ///< plan-view query at the hit point
};

class TunnelWorld {
  public:
    /// Builds the layout, the drivable route and the furniture from the options and seed.
    TunnelWorld(const WorldOptions& options, uint64_t seed);

    const WorldOptions& options() const { return opt_; }
    /// The world's 32-bit seed (a hash of the scenario seed).
    uint32_t seed() const { return seed_; }
    const std::vector<TunnelSegment>& segments() const { return segments_; }
    /// Smoothed drivable centre line, points 0.25 m apart, from the start of the route.
    const std::vector<Eigen::Vector2d>& route() const { return route_; }
    double routeLength() const { return 0.25 * (route_.size() - 1); }
    const std::vector<Cylinder>& cylinders() const { return cylinders_; }
    const std::vector<Lamp>& lamps() const { return lamps_; }
    void addMarker(const CeilingMarker& m) { markers_.push_back(m); }

    /// Plan-view bounding box of all tunnels [m].
    Eigen::Vector2d minCorner() const { return lo_; }
    Eigen::Vector2d maxCorner() const { return hi_; }

    /// Nearest tunnel piece and signed distance to the rock, walls roughened by wallRelief().
    WallQuery query(double x, double y) const;
    /// Relief of the rock walls at a plan point [m] (+ = rock cut back, the tunnel wider),
    /// within +-wall_roughness_m; its gradient in *gx, *gy when given. A pure function of
    /// (x, y, seed): the same rock for every traverse, sensor and map cell.
    double wallRelief(double x, double y, double* gx, double* gy) const;
    /// Height of the roof above the floor at a plan point `dist_to_wall` (= -sdf) from the wall:
    /// the arch near the walls, the ceiling height plus low-frequency relief elsewhere.
    double roofHeight(double x, double y, double dist_to_wall) const;
    /// Unit plan-view direction away from the nearest wall (-grad sdf) at a point of `q`.
    Eigen::Vector2d awayFromWall(double x, double y, const WallQuery& q) const;
    /// Gradient (dz/dx, dz/dy) of roofHeight() at a point of `q` (arch plus relief).
    Eigen::Vector2d roofSlope(double x, double y, const WallQuery& q) const;
    /// Floor height where the vehicle's wheels touch: the level of the grade profile plus a
    /// relief of a few cm that pitches and rolls the vehicle [m].
    double floorHeight(double x, double y) const;
    /// True when the mine has a grade profile (WorldOptions::grade): floor, roof and furniture
    /// then stand on level(), otherwise on z = 0 exactly as before.
    bool graded() const { return !level_.empty(); }
    /// Height of the floor's base surface at a plan point [m]: the grade profile at the route
    /// distance of the nearest point of the route's centre line (side tunnels take the level
    /// of the main tunnel beside them); 0 in a level mine.
    double level(double x, double y) const;
    /// The grade profile itself at route distance s [m] (what level() looks up).
    double levelAtRoute(double s) const;
    /// Bound on |grad level()| (the steepest ramp), 0 in a level mine.
    double maxGrade() const { return max_grade_; }

    /// Ceiling albedo at a plan point; `footprint_m` is the pixel size there (finer detail is
    /// averaged out). Adds the slope of the rock micro-relief to *slope_x, *slope_y.
    double roofAlbedo(double x, double y, const WallQuery& q, double footprint_m, double* slope_x,
                      double* slope_y) const;
    /// Wall albedo at a point of height z on the wall of the piece in `q`.
    double wallAlbedo(const WallQuery& q, double z, double footprint_m) const;
    double floorAlbedo(double x, double y, double footprint_m) const;
    /// Albedo of a furniture surface at `p` (ribs of the duct, ...).
    double objectAlbedo(const Cylinder& c, const Eigen::Vector3d& p) const;

    /// First hit of the ray o + t d (|d| = 1) with roof, walls or floor for t in (t_min, t_max).
    /// `rad_per_px` (angle of one pixel) sets the accuracy needed far away.
    SurfaceHit traceStatic(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min,
                           double t_max, double rad_per_px = 0) const;

    /// Rasterises the tunnels into `grid` (free inside, occupied rock outside, 2 m margin).
    void fillGridMap(mrpt::maps::COccupancyGridMap2D& grid) const;

  private:
    void buildLayout();
    /// The tunnels of each layout (segments, side openings, niches); returns the raw route.
    /// `s_side` is the next texture coordinate free for a side opening.
    std::vector<Eigen::Vector2d> buildSingleTunnel(double* s_side);
    std::vector<Eigen::Vector2d> buildTwinTunnels(double* s_side);
    /// Segments along a main line, texture coordinate s0 at its start.
    void addLine(const std::vector<Eigen::Vector2d>& pts, double s0);
    /// Draw points (short side openings), crossing tunnels and niches along a main line.
    void addSides(const std::vector<Eigen::Vector2d>& pts, uint32_t stream, double flip,
                  double* s_side);
    /// Crossing tunnels; returns their arc lengths along `pts` (of total `length`).
    std::vector<double> addJunctions(const std::vector<Eigen::Vector2d>& pts, double length,
                                     double* s_side);
    /// Draw points away from the junctions, on a random side (times `flip`); their arc
    /// lengths are appended to `openings`.
    void addDrawpoints(const std::vector<Eigen::Vector2d>& pts, double length, uint32_t stream,
                       double flip, const std::vector<double>& junctions,
                       std::vector<double>* openings, double* s_side);
    /// lo_, hi_: the segments' bounding box.
    void computeBounds();
    void buildRoute(const std::vector<Eigen::Vector2d>& raw);
    void buildFurniture(const std::vector<Eigen::Vector2d>& raw);
    void buildBuckets();
    void buildBumps();
    /// Ducts and pipes along the raw route (before the cables: the cylinders' order is part of
    /// the generated bytes).
    void buildServices(const std::vector<Eigen::Vector2d>& raw);
    void addCylinder(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius,
                     SurfaceKind kind);
    void buildLevels(const std::vector<Eigen::Vector2d>& raw);
    SurfaceHit traceGraded(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min,
                           double t_max, double rad_per_px) const;
    void addSegment(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double half_width,
                    double s0, bool on_route);
    bool solid(const Eigen::Vector3d& p, WallQuery* q) const;
    void addNiches(const std::vector<Eigen::Vector2d>& line, uint32_t stream,
                   const std::vector<double>& openings, double* s_side);

    WorldOptions opt_;
    uint32_t seed_;
    std::vector<TunnelSegment> segments_;
    std::vector<Eigen::Vector2d> route_;
    std::vector<Cylinder> cylinders_;
    std::vector<Lamp> lamps_;
    std::vector<CeilingMarker> markers_;
    Eigen::Vector2d lo_, hi_;
    // Plan-view buckets of nearby segments, so a query tests only a few pieces.
    double bucket_m_ = 8.0;
    Eigen::Vector2d bucket_origin_;
    int bucket_nx_ = 0, bucket_ny_ = 0;
    std::vector<std::vector<int>> buckets_;
    // Ceiling relief sampled every kBumpCell metres over the bounding box (bilinear), so the
    // inner loops of the ray caster do not evaluate noise.
    double bumpAt(double x, double y, double* gx, double* gy) const;
    std::vector<float> bump_;
    // Wall relief, sampled likewise (finer: its shortest wavelength is 0.5 m).
    void buildRelief();
    std::vector<float> relief_;
    int relief_nx_ = 0, relief_ny_ = 0;
    double relief_lipschitz_ = 0;  ///< bound on |grad wallRelief| (sphere-tracing step)
    int bump_nx_ = 0, bump_ny_ = 0;
    Eigen::Vector2d bump_origin_;
    // Grade profile: z per kLevelStep of route distance, and level() sampled every kLevelCell
    // metres over the bounding box (bilinear; empty = a level mine).
    std::vector<double> profile_;
    std::vector<float> level_;
    int level_nx_ = 0, level_ny_ = 0;
    double max_grade_ = 0;
    // Optional user texture (grey, row-major) tiled over the ceiling.
    std::vector<float> tex_;
    int tex_w_ = 0, tex_h_ = 0;
};

}  // namespace lookup::sim
