#pragma once
// CObservationLookupResult: one localisation fix of lookup-localize (paper Sec. III-D/E): the
// estimated vehicle pose with covariance, the outcome, and the per-reference evidence
// (RANSAC inliers/outliers and, optionally, the matched flow lines for display). Registered
// with mrpt-rtti in liblookup_obs.so so RawLogViewer shows it.

#include <mrpt/obs/CObservation.h>
#include <mrpt/poses/CPose3DPDFGaussian.h>
#include <mrpt/serialization/CSerializable.h>

#include <cstdint>
#include <string>
#include <vector>

namespace lookup::obs {

/// Outcome of one localisation query.
enum class LookupStatus : uint8_t {
    Refined = 0,     ///< fine (ceiling) estimate accepted
    CoarseOnly = 1,  ///< refinement rejected (N_th / d_th), coarse reference pose reported
    Failed = 2,      ///< no estimate at all
};

const char* toString(LookupStatus s);

/// Evidence from one reference used in a query.
struct ReferenceEvidence {
    uint32_t reference_id = 0;  ///< database reference index
    uint32_t inliers = 0;       ///< RANSAC homography inliers
    uint32_t outliers = 0;      ///< matched points rejected by RANSAC
};

/// One matched point: reference pixel (u0, v0) to query pixel (u1, v1) [px].
struct FlowLine {
    uint32_t reference_id = 0;
    float u0 = 0, v0 = 0, u1 = 0, v1 = 0;
    bool inlier = false;
};

class CObservationLookupResult : public mrpt::obs::CObservation {
    DEFINE_SERIALIZABLE(CObservationLookupResult, lookup::obs)

  public:
    /// Estimated vehicle pose in the map frame with its 6x6 covariance [m, rad].
    mrpt::poses::CPose3DPDFGaussian pose;
    LookupStatus status = LookupStatus::Failed;
    /// Why the status is what it is (empty when Refined).
    std::string reason;
    /// Reference chosen by the coarse stage (forward-image sequence matcher).
    uint32_t coarse_reference_id = 0;
    /// Estimated ceiling distance h - z_c [m] (0 if not estimated).
    double ceiling_distance_m = 0;
    /// Wall time spent on this query [s].
    double processing_time_s = 0;
    std::vector<ReferenceEvidence> references;
    std::vector<FlowLine> flows;  ///< optional, for display

    /// Sensor pose = the ceiling camera mounting pose of the query.
    mrpt::poses::CPose3D sensorPose;

    void getSensorPose(mrpt::poses::CPose3D& out_sensor_pose) const override;
    void setSensorPose(const mrpt::poses::CPose3D& new_sensor_pose) override;
    void getDescriptionAsText(std::ostream& o) const override;
};

}  // namespace lookup::obs
