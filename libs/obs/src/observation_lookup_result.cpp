#include "lookup/obs/observation_lookup_result.h"

#include <mrpt/serialization/CArchive.h>

#include <ostream>

namespace lookup::obs {

IMPLEMENTS_SERIALIZABLE(CObservationLookupResult, mrpt::obs::CObservation, lookup::obs)

const char* toString(LookupStatus s) {
    switch (s) {
        case LookupStatus::Refined:
            return "refined";
        case LookupStatus::CoarseOnly:
            return "coarse-only";
        case LookupStatus::Failed:
            return "failed";
    }
    return "unknown";
}

uint8_t CObservationLookupResult::serializeGetVersion() const { return 0; }

void CObservationLookupResult::serializeTo(mrpt::serialization::CArchive& out) const {
    out << timestamp << sensorLabel << sensorPose << pose;
    out << static_cast<uint8_t>(status) << reason << coarse_reference_id << ceiling_distance_m
        << processing_time_s;
    out << static_cast<uint32_t>(references.size());
    for (const auto& r : references) out << r.reference_id << r.inliers << r.outliers;
    out << static_cast<uint32_t>(flows.size());
    for (const auto& f : flows) out << f.reference_id << f.u0 << f.v0 << f.u1 << f.v1 << f.inlier;
}

void CObservationLookupResult::serializeFrom(mrpt::serialization::CArchive& in, uint8_t version) {
    switch (version) {
        case 0: {
            in >> timestamp >> sensorLabel >> sensorPose >> pose;
            uint8_t s = 0;
            in >> s >> reason >> coarse_reference_id >> ceiling_distance_m >> processing_time_s;
            if (s > static_cast<uint8_t>(LookupStatus::Failed)) {
                THROW_EXCEPTION_FMT("CObservationLookupResult: invalid status value %u",
                                    unsigned(s));
            }
            status = static_cast<LookupStatus>(s);
            uint32_t n = 0;
            in >> n;
            references.resize(n);
            for (auto& r : references) in >> r.reference_id >> r.inliers >> r.outliers;
            in >> n;
            flows.resize(n);
            for (auto& f : flows) in >> f.reference_id >> f.u0 >> f.v0 >> f.u1 >> f.v1 >> f.inlier;
        } break;
        default:
            MRPT_THROW_UNKNOWN_SERIALIZATION_VERSION(version);
    }
}

void CObservationLookupResult::getSensorPose(mrpt::poses::CPose3D& out_sensor_pose) const {
    out_sensor_pose = sensorPose;
}

void CObservationLookupResult::setSensorPose(const mrpt::poses::CPose3D& new_sensor_pose) {
    sensorPose = new_sensor_pose;
}

void CObservationLookupResult::getDescriptionAsText(std::ostream& o) const {
    CObservation::getDescriptionAsText(o);
    o << "LookUP localisation result: " << toString(status);
    if (!reason.empty()) o << " (" << reason << ")";
    o << "\nPose in map (x y z yaw pitch roll): " << pose.mean.asString() << "\n";
    o << "Std: x=" << std::sqrt(pose.cov(0, 0)) << " m, y=" << std::sqrt(pose.cov(1, 1))
      << " m, yaw=" << mrpt::RAD2DEG(std::sqrt(pose.cov(3, 3))) << " deg\n";
    o << "Coarse reference: #" << coarse_reference_id
      << ", ceiling distance: " << ceiling_distance_m << " m, time: " << processing_time_s
      << " s\n";
    o << "References (id: inliers/outliers):";
    for (const auto& r : references)
        o << " #" << r.reference_id << ": " << r.inliers << "/" << r.outliers;
    o << "\nFlow lines: " << flows.size() << "\n";
}

}  // namespace lookup::obs
