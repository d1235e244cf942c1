#pragma once
// Rolling shutter: a camera that exposes its rows one after another sees each row from where
// the vehicle was at that row's time. Row v is exposed at
//   stamp + (v - stamp_row) * readout / (rows - 1)
// (docs/sim.md, `readout_ms`, `stamp_row`); at 40 km/h a 30 ms readout moves the vehicle 0.33 m
// between the first and the last row, so the image is a ceiling stretched or sheared along the
// drive, not one view of it. The estimator moves each point's camera by the vehicle's
// velocity times its row's time (RowTiming::motionAtRow).

#include <mrpt/poses/CPose2D.h>
#include <mrpt/poses/CPose3D.h>

namespace lookup::refine {

/// Vehicle velocity in its own frame (x ahead, y left) at a frame's stamp.
struct VehicleMotion {
    double vx_mps = 0, vy_mps = 0;  ///< [m/s]
    double yaw_rate_radps = 0;      ///< [rad/s]
    bool moving() const { return vx_mps != 0.0 || vy_mps != 0.0 || yaw_rate_radps != 0.0; }
};

/// When each row of one image was exposed, and how the vehicle moved meanwhile.
struct RowTiming {
    double readout_s = 0;  ///< first row to last row [s]; 0 = global shutter
    double stamp_row = 0;  ///< row exposed at the stamp (0: first row, (rows - 1) / 2: middle)
    int rows = 0;          ///< image height [px]
    VehicleMotion velocity;

    /// Whether any row was seen from elsewhere than the stamp's pose.
    bool active() const { return readout_s > 0.0 && rows > 1 && velocity.moving(); }
    /// Time of row `v` after the stamp [s].
    double timeOfRow(double v) const {
        return rows > 1 ? (v - stamp_row) * readout_s / double(rows - 1) : 0.0;
    }
    /// The vehicle's pose at row `v`'s exposure in its own frame at the stamp (constant
    /// velocity and yaw rate over the readout).
    mrpt::poses::CPose2D motionAtRow(double v) const;
    /// A camera at `camera_in_map` on a vehicle (mount `camera_on_vehicle`) at the stamp, moved
    /// to row `v`'s exposure.
    mrpt::poses::CPose3D cameraAtRow(const mrpt::poses::CPose3D& camera_in_map,
                                     const mrpt::poses::CPose3D& camera_on_vehicle, double v) const;
};

}  // namespace lookup::refine
