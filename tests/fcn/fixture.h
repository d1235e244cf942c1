#pragma once
// Test fixture for the FCN: a textured ceiling (z = 5 m) with "pipes", bright striped bands on a
// lower plane (z = 3.5 m) crossing the tunnel every 2 m. Between two views the pipes move
// differently from the ceiling (parallax), so RANSAC labels them outliers: the network must
// learn to score them low. Tiny images (160 x 120) keep every test fast.

#include <filesystem>
#include <string>
#include <vector>

#include "lookup/common/pose_files.h"
#include "lookup/fcn/options.h"
#include "lookup/refine/testing/synthetic_ceiling.h"
#include "lookup/test/support.h"

namespace lookup::fcn::fixture {

constexpr double kCeilingHeight = 5.0;
constexpr double kPipeHeight = 3.5;
constexpr double kT0 = 1.7e9;

struct PipeScene {
    refine::synthetic::SyntheticCeiling ceiling, pipes, mask;
    mrpt::img::TCamera camera;
    mrpt::poses::CPose3D mount;

    PipeScene();
    /// Ceiling camera image of a vehicle at `vehicle` (CV_8UC1).
    cv::Mat render(const mrpt::poses::CPose3D& vehicle) const;
    /// 255 where a pipe is seen, 0 elsewhere (CV_8UC1).
    cv::Mat pipeMask(const mrpt::poses::CPose3D& vehicle) const;
};
const PipeScene& scene();

/// A database of references along y = 0 at the given x [m] (survey times 100 + 0.1 k s).
void writeDatabase(const std::string& dir, const std::vector<double>& xs);
/// A query rawlog (ceiling images labelled CEILING_CAM) and its poses, posesFile(rawlog).
void writeQuery(const std::string& rawlog, const common::PoseTrack& track);
/// Where writeQuery writes the drive's poses (MRPT pose file).
std::string posesFile(const std::string& rawlog);
/// A straight query drive along y = `y` from x0 to x1 every `step` m, 10 frames/s from kT0.
common::PoseTrack drive(double x0, double x1, double step, double y);

/// Options sized for the fixture (patch 20 px, window 24 px, grid step 8 px, small network).
TrainOptions smallOptions();

}  // namespace lookup::fcn::fixture
