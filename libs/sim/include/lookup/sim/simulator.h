#pragma once
// lookup-sim as a library: generates a synthetic mine dataset (docs/dataset-format.md) from a
// scenario: one observations-only rawlog with external images and one ground-truth file per
// traverse, plus the map, dataset.ini and the resolved scenario.ini. Same seed, same bytes.

#include "lookup/sim/scenario.h"
#include "lookup/sim/world.h"

#include <lookup/common/pose_files.h>
#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/poses/CPose2D.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace lookup::sim {

/// What one traverse produced.
struct TraverseSummary {
    std::string name;
    std::string roles;
    std::size_t ceiling_frames = 0;
    std::size_t forward_frames = 0;
    std::size_t lidar_scans = 0;
    std::size_t odometry_records = 0;
    std::size_t ground_truth_rows = 0;
    double length_m = 0;      ///< distance driven [m]
    double duration_s = 0;    ///< from first to last ground-truth row [s]
    double start_time_s = 0;  ///< absolute time stamp of the start [s]
    uint64_t bytes = 0;       ///< rawlog + images + ground truth [bytes]
    double wall_time_s = 0;   ///< generation time [s]
};

struct SimulationResult {
    enum class Status { Ok, Failed };
    Status status = Status::Failed;
    std::string reason;  ///< why it failed (file and cause), empty when Ok
    std::string out_dir;
    std::vector<TraverseSummary> traverses;
    uint64_t total_bytes = 0;  ///< everything written into out_dir [bytes]
    double wall_time_s = 0;    ///< total generation time [s]
};

/// Human-readable table, one line per traverse plus a total.
std::string formatSummary(const SimulationResult& result);

/// A vehicle's drive along the route: dense ground truth (100 Hz) in the traverse's time base.
common::PoseTrack vehicleTrack(const TunnelWorld& world, const TraverseOptions& traverse,
                               const VehicleOptions& vehicle, double start_time_s);

/// One scan of the 2-D lidar at `vehicle` (map frame): each ray traced against the world's rock
/// surface (TunnelWorld::traceStatic, the surface the cameras see, rough walls included) in
/// the horizontal plane at the mount height, plus Gaussian range noise drawn deterministically
/// from `noise_key`. Rays that reach no rock within range are invalid. (Scans were once cast
/// into the 0.1 m occupancy grid: its walls are staircases aligned with the map axes, and scan
/// matching against them was biased by the tunnel's heading, 0.4 % in length and up to
/// 0.007 deg/m in heading, which ICP-SLAM integrated over 1 km into metres.)
/// `vehicle_at_end` (optional): the vehicle when the last ray is measured; rays in between
/// are taken from poses interpolated along the sweep (scan skew), the scan's stamp being the
/// first ray's. Dust returns (`dust_rate`) replace a ray's range by a short one.
mrpt::obs::CObservation2DRangeScan simulateLidar(
    const TunnelWorld& world, const mrpt::poses::CPose2D& vehicle, const LidarOptions& lidar,
    uint32_t noise_key, const mrpt::poses::CPose2D* vehicle_at_end = nullptr);

/// The scanner on a vehicle with its full attitude (x, y, z, yaw, pitch, roll). In a level
/// mine: the model above, bit for bit (the scan plane stays horizontal at the mount height).
/// On a grade (TunnelWorld::graded()) the scan plane is the scanner's own x-y plane, tilted
/// with the vehicle: its rays meet the walls at an angle and, where the grade changes under
/// the vehicle, may reach the floor or the roof; those ranges are what it returns.
mrpt::obs::CObservation2DRangeScan simulateLidar(
    const TunnelWorld& world, const mrpt::poses::CPose3D& vehicle, const LidarOptions& lidar,
    uint32_t noise_key, const mrpt::poses::CPose3D* vehicle_at_end = nullptr);

class Simulator {
  public:
    /// Called now and then during run(): traverse name and its fraction done in [0, 1].
    using Progress = std::function<void(const std::string& traverse, double fraction)>;

    /// Checks the scenario (common::ConfigError naming the field) and builds the world.
    explicit Simulator(ScenarioOptions scenario);
    ~Simulator();

    const ScenarioOptions& scenario() const { return scenario_; }
    const TunnelWorld& world() const { return *world_; }
    /// For tests: paint a marker on the ceiling before run().
    TunnelWorld& mutableWorld() { return *world_; }

    /// Ground truth of traverse i (dense, 100 Hz, absolute time stamps). Traverse k starts at
    /// start_time_s + k * traverse_gap_s, or 10 s after the previous one ends if that is later.
    const common::PoseTrack& groundTruth(std::size_t i) const { return tracks_.at(i); }

    /// What the scenario asks for and does not get, one line each: a traverse without a plan
    /// that never comes within 10 % of its speed_kmh (accelerating from rest and braking to a
    /// stop at accel_mps2 over a route too short for it).
    const std::vector<std::string>& warnings() const { return warnings_; }

    /// Writes the dataset into `out_dir` (created if needed; files of the same names are
    /// replaced). Failures (unwritable folder, full disk) come back as Status::Failed with the
    /// file and cause, not as exceptions.
    SimulationResult run(const std::string& out_dir, const Progress& progress = {}) const;

  private:
    TraverseSummary runTraverse(std::size_t index, const std::string& out_dir,
                                const mrpt::maps::COccupancyGridMap2D& grid,
                                const Progress& progress) const;

    /// Plan targets beyond the route's end: ConfigError naming the file, traverse and leg.
    void checkPlansOnRoute() const;
    /// A lens distortion that leaves some pixel without a ray: ConfigError naming the section.
    void checkLenses() const;
    void noteSpeedsNotReached();

    ScenarioOptions scenario_;
    std::unique_ptr<TunnelWorld> world_;
    /// Per traverse: its own-appearance world ([traverse_i.world]), null = world_.
    std::vector<std::unique_ptr<TunnelWorld>> traverse_worlds_;
    std::vector<common::PoseTrack> tracks_;
    std::vector<std::string> warnings_;
};

}  // namespace lookup::sim
