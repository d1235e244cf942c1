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

/// What the camera measured of its own frame (for the auto-exposure loop).
struct FrameStats {
    double mean_dn = 0;  ///< mean grey level of the delivered image [DN]
};

class CameraRenderer {
  public:
    enum class Kind {
        Ceiling,  ///< looks up: fast path for the quasi-planar roof, headlight on the axis
        Forward   ///< looks along the tunnel: tone-mapped, lamps light the walls
    };

    /// `threads` = 0: all cores. The image does not depend on the thread count.
    CameraRenderer(const TunnelWorld& world, const CameraOptions& camera, Kind kind, int threads);

    /// Intrinsics: fx = fy = (width/2) / tan(hfov/2), principal point at the image centre
    /// ((width-1)/2, (height-1)/2), and the lens distortion of the options (none, plumb_bob or
    /// kannala_brandt), as a calibration would record them. Each pixel is rendered along the
    /// exact ray this model gives it (the distortion inverted per pixel), so the image has no
    /// resampling blur and no black borders.
    const mrpt::img::TCamera& intrinsics() const { return camera_; }

    /// Renders the view of a camera whose frame (+Z optical axis, +X right, +Y down) has pose
    /// `camera_in_map`. Returns a grey 8-bit image; `stats` (optional) gets its mean level.
    mrpt::img::CImage render(const mrpt::poses::CPose3D& camera_in_map,
                             const FrameConditions& frame, FrameStats* stats = nullptr) const;
    /// Rolling shutter: row v seen from `row_poses[v]` (one pose per image row).
    mrpt::img::CImage render(const std::vector<mrpt::poses::CPose3D>& row_poses,
                             const FrameConditions& frame, FrameStats* stats = nullptr) const;

    /// Normalised undistorted coordinates (x/z, y/z) of a distorted pixel (u, v) under `camera`
    /// (Gauss-Newton inversion of its distortion to 1e-12 px); false if it does not converge.
    static bool undistortPixel(const mrpt::img::TCamera& camera, double u, double v, double* x,
                               double* y);
    /// Pixel of the normalised point (x, y) (ray (x, y, 1)) under `camera`'s distortion.
    static void distortPoint(const mrpt::img::TCamera& camera, double x, double y, double* u,
                             double* v);

  private:
    /// A furniture piece and the image rectangle it can cover in the current frame.
    struct ObjectInView {
        int index = 0;
        int u0 = 0, u1 = 0, v0 = 0, v1 = 0;  ///< in undistorted (pinhole) pixel coordinates
    };
    /// One camera pose and what can be seen from it.
    struct View {
        Eigen::Matrix3d R;
        Eigen::Vector3d o;
        std::vector<ObjectInView> cylinders;
        std::vector<int> lamps;
    };
    View makeView(const mrpt::poses::CPose3D& camera_in_map) const;
    void renderRows(const std::vector<View>& views, int first, int step, float* out,
                    float* depth) const;
    double shadePixel(int index, const View& view, double* depth) const;
    /// Nearest furniture cylinder along pixel `index`'s ray (direction d in the map) nearer
    /// than t_max: its distance, `normal` and `object` (index into the world's cylinders), or
    /// t_max with both untouched.
    double nearestCylinder(int index, const View& view, const Eigen::Vector3d& d, double t_max,
                           Eigen::Vector3d* normal, int* object) const;
    void buildRays();
    void buildLensMasks();
    /// Radiance (and depth) to the delivered 8-bit image: haze, motion blur, lens drops and
    /// dirt, exposure, bloom, tone curve, noise, response.
    mrpt::img::CImage develop(std::vector<float>& radiance, const std::vector<float>& depth,
                              const FrameConditions& frame, FrameStats* stats) const;

    const TunnelWorld& world_;
    CameraOptions opt_;
    Kind kind_;
    int threads_;
    mrpt::img::TCamera camera_;
    std::vector<Eigen::Vector3d> rays_;  ///< unit ray per pixel in the camera frame
    std::vector<float> pin_u_, pin_v_;   ///< undistorted (pinhole) coordinates per pixel
    double pin_lo_u_ = 0, pin_hi_u_ = 0, pin_lo_v_ = 0, pin_hi_v_ = 0;  ///< their range
    bool cull_ = true;          ///< image-rectangle culling valid (no ray at or behind 90 deg)
    std::vector<float> dirt_;   ///< lens transmission per pixel (1: clean), empty = no dirt
    std::vector<float> drops_;  ///< water-drop cover per pixel in [0, 1], empty = no drops
    uint32_t lens_seed_ = 0;    ///< where this camera's dirt and drops lie
    std::vector<double> beam_;  ///< vehicle-light beam factor per pixel
    double half_diag_fov_ = 0;  ///< [rad]
};

}  // namespace lookup::sim
