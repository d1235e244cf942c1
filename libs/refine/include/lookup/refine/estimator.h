#pragma once
// Joint pose-and-scale estimate (paper Sec. III-D, done as one least-squares problem here):
// every inlier reference pixel is back-projected through its surveyed camera onto the ceiling
// plane z = h (poses in the references' floor frame: the Refiner turns a grade into it) and
// projected into the query camera; Ceres minimises the pixel residuals over
// the query vehicle pose (x, y, yaw, small pitch and roll; z held at `vehicle_z`) and h, with
// a Huber loss, a prior on h (so one reference suffices) and a prior on pitch/roll. With two
// or more references at different surveyed positions h is observable from the images.
// The start comes in closed form: a 2-D rigid alignment (Umeyama) of the back-projected points.
// With a rolling shutter (RowTiming active) each pixel is seen from the camera moved to its
// row's exposure: the reference's back-projection and the query's projection alike.

#include <mrpt/math/CMatrixFixed.h>
#include <mrpt/poses/CPose3D.h>
#include <mrpt/poses/CPosePDFGaussian.h>

#include <optional>
#include <string>
#include <vector>

#include "lookup/refine/geometry.h"
#include "lookup/refine/options.h"
#include "lookup/refine/rolling_shutter.h"

namespace lookup::refine {

/// Inlier correspondences of one reference.
struct ReferenceView {
    Pinhole camera;
    mrpt::poses::CPose3D camera_in_map;     ///< surveyed
    std::vector<cv::Point2d> reference_px;  ///< rectified pixels
    std::vector<cv::Point2d> query_px;      ///< matching query pixels
    /// Rows of each point as the sensors read them (before rectification), for the row
    /// times; empty = the rectified pixels' y.
    std::vector<double> reference_row, query_row;
    RowTiming timing;                        ///< of the reference image (survey vehicle)
    mrpt::poses::CPose3D camera_on_vehicle;  ///< reference camera mount (with `timing`)
};

struct EstimatorInput {
    std::vector<ReferenceView> views;
    Pinhole query_camera;
    mrpt::poses::CPose3D query_camera_on_vehicle;
    double vehicle_z = 0.0;        ///< query vehicle z [m], held fixed
    double prior_pitch_rad = 0.0;  ///< centre of the tilt prior
    double prior_roll_rad = 0.0;
    double ceiling_height_m = 5.0;  ///< centre of the h prior [m]
    RowTiming query_timing;         ///< the query image's rows (velocity: the query vehicle's)
    int query_rows = 0;             ///< the query image's height [px] (for row_travel)
};

/// What the query's rows show of a rolling shutter the model does not carry: the vehicle's
/// travel along its heading from the first row's exposure to the last, as the residuals'
/// stretch along the drive that grows with the row (rolling_shutter.h). Measured after the
/// solve, the pose left as solved.
struct RowTravel {
    double travel_m = 0;  ///< signed: forward travel of a late last row positive [m]
    double sigma_m = 0;   ///< its standard deviation [m]
};

/// Covariance order of `covariance`: x, y, yaw, pitch, roll, h.
struct PoseEstimate {
    bool ok = false;
    std::string reason;
    mrpt::poses::CPose3D vehicle_in_map;
    mrpt::poses::CPosePDFGaussian pose;  ///< (x, y, yaw) with its 3x3 covariance
    mrpt::math::CMatrixDouble66 covariance;
    double ceiling_height_m = 0.0;
    double ceiling_height_sigma_m = 0.0;
    double rms_residual_px = 0.0;  ///< over all correspondences at the solution
    int correspondences = 0;
    int iterations = 0;
    std::optional<RowTravel> row_travel;  ///< when the rows could show it
};

PoseEstimate estimateQueryPose(const EstimatorInput& input, const EstimatorOptions& options);

}  // namespace lookup::refine
