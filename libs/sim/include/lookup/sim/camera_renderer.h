#pragma once
// Grey pinhole cameras rendered by per-pixel ray casting against the tunnel (roof with relief,
// arched walls, floor) and its furniture (ducts, pipes, cables, lamps), lit by the vehicle's own
// light (falloff with distance and off-axis angle) and the tunnel lamps.

#include "lookup/sim/scenario.h"
#include "lookup/sim/world.h"

#include <mrpt/img/CImage.h>
#include <mrpt/img/TCamera.h>
#include <mrpt/poses/CPose3D.h>

#include <cstdint>
#include <vector>

namespace lookup::sim {

/// What changes from frame to frame besides the pose.
struct FrameConditions {
    double exposure_gain = 1.0;  ///< brightness multiplier (auto-exposure changes)
    double blur_u_px = 0;        ///< image motion during the exposure, u component [px]
    double blur_v_px = 0;        ///< ... v component [px]
    uint32_t noise_key = 0;      ///< selects the sensor-noise pattern (hash of seed and frame)
};

class CameraRenderer {
  public:
    enum class Kind {
        Ceiling,  ///< looks up: fast path for the quasi-planar roof, headlight on the axis
        Forward   ///< looks along the tunnel: tone-mapped, lamps light the walls
    };

    /// `threads` = 0: all cores. The image does not depend on the thread count.
    CameraRenderer(const TunnelWorld& world, const CameraOptions& camera, Kind kind, int threads);

    /// Pinhole intrinsics: fx = fy = (width/2) / tan(hfov/2), principal point at the image centre
    /// ((width-1)/2, (height-1)/2), no distortion.
    const mrpt::img::TCamera& intrinsics() const { return camera_; }

    /// Renders the view of a camera whose frame (+Z optical axis, +X right, +Y down) has pose
    /// `camera_in_map`. Returns a grey 8-bit image.
    mrpt::img::CImage render(const mrpt::poses::CPose3D& camera_in_map,
                             const FrameConditions& frame) const;

  private:
    /// A furniture piece and the image rectangle it can cover in the current frame.
    struct ObjectInView {
        int index = 0;
        int u0 = 0, u1 = 0, v0 = 0, v1 = 0;
    };
    void renderRows(const Eigen::Matrix3d& R, const Eigen::Vector3d& o,
                    const std::vector<ObjectInView>& cylinders, const std::vector<int>& lamps,
                    int first, int step, float* out) const;
    double shadePixel(int index, const Eigen::Matrix3d& R, const Eigen::Vector3d& o,
                      const std::vector<ObjectInView>& cylinders,
                      const std::vector<int>& lamps) const;

    const TunnelWorld& world_;
    CameraOptions opt_;
    Kind kind_;
    int threads_;
    mrpt::img::TCamera camera_;
    std::vector<Eigen::Vector3d> rays_;  ///< unit ray per pixel in the camera frame
    std::vector<double> beam_;           ///< vehicle-light beam factor per pixel
    double half_diag_fov_ = 0;           ///< [rad]
};

}  // namespace lookup::sim
