#include "lookup/obs/observation_lookup_reference.h"

#include <mrpt/serialization/CArchive.h>

#include <ostream>

namespace lookup::obs {

namespace {
std::string modelName(mrpt::img::DistortionModel m) {
    switch (m) {
        case mrpt::img::DistortionModel::none:
            return "none";
        case mrpt::img::DistortionModel::plumb_bob:
            return "plumb_bob";
        case mrpt::img::DistortionModel::kannala_brandt:
            return "kannala_brandt";
        default:
            return "unknown (" + std::to_string(int(m)) + ")";
    }
}
}  // namespace

IMPLEMENTS_SERIALIZABLE(CObservationLookupReference, mrpt::obs::CObservation, lookup::obs)

uint8_t CObservationLookupReference::serializeGetVersion() const { return 2; }

void CObservationLookupReference::serializeTo(mrpt::serialization::CArchive& out) const {
    out << timestamp << sensorLabel << sensorPose;
    out << reference_id << traverse << vehicle_pose;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) out << vehicle_cov(r, c);
    out << ceiling_camera_pose << forward_camera_pose << ceiling_image_file << forward_image_file
        << forward_time_s << sharpness << mean_intensity << travelled_m;
    out << has_ceiling_camera << ceiling_camera;
    out << source << superseded_by;
}

void CObservationLookupReference::serializeFrom(mrpt::serialization::CArchive& in,
                                                uint8_t version) {
    switch (version) {
        case 0:
        case 1:
        case 2: {
            in >> timestamp >> sensorLabel >> sensorPose;
            in >> reference_id >> traverse >> vehicle_pose;
            for (int r = 0; r < 3; ++r)
                for (int c = 0; c < 3; ++c) in >> vehicle_cov(r, c);
            in >> ceiling_camera_pose >> forward_camera_pose >> ceiling_image_file >>
                forward_image_file >> forward_time_s >> sharpness >> mean_intensity >> travelled_m;
            has_ceiling_camera = false;
            ceiling_camera = mrpt::img::TCamera();
            if (version >= 1) in >> has_ceiling_camera >> ceiling_camera;
            source = "survey";
            superseded_by.clear();
            if (version >= 2) in >> source >> superseded_by;
        } break;
        default:
            MRPT_THROW_UNKNOWN_SERIALIZATION_VERSION(version);
    }
}

void CObservationLookupReference::getSensorPose(mrpt::poses::CPose3D& out_sensor_pose) const {
    out_sensor_pose = sensorPose;
}

void CObservationLookupReference::setSensorPose(const mrpt::poses::CPose3D& new_sensor_pose) {
    sensorPose = new_sensor_pose;
}

void CObservationLookupReference::getDescriptionAsText(std::ostream& o) const {
    CObservation::getDescriptionAsText(o);
    o << "LookUP reference #" << reference_id << " of traverse '" << traverse << "' (" << source
      << ")\n";
    if (!superseded_by.empty()) {
        o << "Superseded: the ceiling changed here, seen by '" << superseded_by << "'\n";
    }
    o << "Vehicle pose in map (x y z yaw pitch roll): " << vehicle_pose.asString() << "\n";
    o << "Vehicle pose std: x=" << std::sqrt(vehicle_cov(0, 0))
      << " m, y=" << std::sqrt(vehicle_cov(1, 1))
      << " m, yaw=" << mrpt::RAD2DEG(std::sqrt(vehicle_cov(2, 2))) << " deg\n";
    o << "Ceiling camera pose in map: " << ceiling_camera_pose.asString() << "\n";
    o << "Forward camera pose in map: " << forward_camera_pose.asString() << "\n";
    o << "Ceiling image: " << ceiling_image_file << "\n";
    o << "Forward image: " << forward_image_file << " (t=" << std::fixed << forward_time_s << ")\n";
    o << "Sharpness (var. of Laplacian): " << sharpness << ", mean intensity: " << mean_intensity
      << "\n";
    o << "Travelled along traverse: " << travelled_m << " m\n";
    if (has_ceiling_camera) {
        o << "Ceiling camera: " << ceiling_camera.ncols << "x" << ceiling_camera.nrows
          << " px, fx=" << ceiling_camera.fx() << " fy=" << ceiling_camera.fy()
          << " cx=" << ceiling_camera.cx() << " cy=" << ceiling_camera.cy() << ", distortion "
          << modelName(ceiling_camera.distortion) << "\n";
    } else {
        o << "Ceiling camera: the database's (db.ini [ceiling_camera])\n";
    }
}

}  // namespace lookup::obs
