#pragma once
// CObservationLookupReference: one reference of the LookUP database (paper Sec. III-A, "the
// reference database"), tying together the records stored beside it in refs.rawlog: the
// ceiling CObservationImage, the forward CObservationImage nearest in time and the
// CObservationRobotPose of the survey. Registered with mrpt-rtti so RawLogViewer shows it when
// liblookup_obs.so is loaded (`RawLogViewer -l liblookup_obs.so refs.rawlog`).

#include <mrpt/img/TCamera.h>
#include <mrpt/math/CMatrixFixed.h>
#include <mrpt/obs/CObservation.h>
#include <mrpt/poses/CPose3D.h>
#include <mrpt/serialization/CSerializable.h>

#include <cstdint>
#include <string>

namespace lookup::obs {

class CObservationLookupReference : public mrpt::obs::CObservation {
    DEFINE_SERIALIZABLE(CObservationLookupReference, lookup::obs)

  public:
    /// Index of the reference in the database (0-based, dense, in refs.rawlog order).
    uint32_t reference_id = 0;
    /// Name of the survey traverse the reference came from.
    std::string traverse;
    /// Vehicle (base frame) pose in the map frame at the ceiling image time stamp [m, rad].
    mrpt::poses::CPose3D vehicle_pose;
    /// Covariance of the vehicle pose over (x [m], y [m], yaw [rad]).
    mrpt::math::CMatrixDouble33 vehicle_cov;
    /// Ceiling camera pose in the map frame: vehicle_pose ⊕ ceiling camera mounting pose.
    mrpt::poses::CPose3D ceiling_camera_pose;
    /// Forward camera pose in the map frame at the forward image time stamp (identity if none).
    mrpt::poses::CPose3D forward_camera_pose;
    /// Image files, relative to the database's refs_Images/ folder ("" = none).
    std::string ceiling_image_file;
    std::string forward_image_file;
    /// Time stamp of the forward image (the coarse stage's key) [s, mrpt::Clock::toDouble].
    double forward_time_s = 0;
    /// Ceiling image sharpness: variance of the Laplacian [grey levels^2].
    double sharpness = 0;
    /// Ceiling image mean intensity [0..255].
    double mean_intensity = 0;
    /// Distance travelled along the traverse at this reference [m].
    double travelled_m = 0;
    /// Intrinsics and distortion of this reference's ceiling image (its camera's calibration).
    /// Records of version 0 (databases written before references kept their own) have none:
    /// has_ceiling_camera is false and the database's db.ini [ceiling_camera] applies.
    bool has_ceiling_camera = false;
    mrpt::img::TCamera ceiling_camera;
    /// Where the reference came from: "survey" (a surveyed traverse) or "refresh" (an
    /// operating drive's image, posed by the localiser's fixes, added where the ceiling had
    /// changed). Records before version 2: "survey".
    std::string source = "survey";
    /// Non-empty: the operating drive (traverse name) over which this reference's ceiling no
    /// longer matched; kept for inspection, no longer used for localisation.
    std::string superseded_by;

    /// Sensor pose = the ceiling camera's mounting pose on the vehicle.
    mrpt::poses::CPose3D sensorPose;

    void getSensorPose(mrpt::poses::CPose3D& out_sensor_pose) const override;
    void setSensorPose(const mrpt::poses::CPose3D& new_sensor_pose) override;
    void getDescriptionAsText(std::ostream& o) const override;
};

}  // namespace lookup::obs
