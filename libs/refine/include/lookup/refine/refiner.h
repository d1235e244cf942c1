#pragma once
// LookUP's precise localisation unit (paper Sec. III): per ceiling query frame,
// select sample points on each reference -> match them into the query -> RANSAC homography
// per reference -> joint Ceres estimate of the query pose and the ceiling height over all
// references' inliers -> acceptance (inlier share >= N_th, offset <= d_th), else fall back to
// the coarse pose. The result is a value: status, reason, pose with covariance, per-reference
// matches and timings. Only broken contracts (invalid options) throw.

#include <mrpt/obs/CObservationImage.h>
#include <mrpt/poses/CPosePDFGaussian.h>

#include <cstdint>
#include <string>
#include <vector>

#include "lookup/refine/acceptance.h"
#include "lookup/refine/estimator.h"
#include "lookup/refine/homography.h"
#include "lookup/refine/options.h"
#include "lookup/refine/types.h"

namespace lookup::refine {

/// Where RefineResult::pose comes from.
enum class PoseSource { Refined, Coarse, Reference, None };
const char* toString(PoseSource s);

struct ReferenceOutcome {
    std::int64_t id = -1;
    std::vector<PointMatch> matches;  ///< one per sample point, with inlier flags
    HomographyResult homography;
};

/// Wall time per stage [ms].
struct StageTimes {
    double prepare_ms = 0;  ///< image conversion and pyramids
    double select_ms = 0;
    double match_ms = 0;
    double homography_ms = 0;
    double estimate_ms = 0;
    double total_ms = 0;
};

struct RefineResult {
    RefineStatus status = RefineStatus::NoReferences;
    std::string reason;  ///< empty when accepted
    bool accepted() const { return status == RefineStatus::Accepted; }

    PoseSource source = PoseSource::None;
    mrpt::poses::CPosePDFGaussian pose;  ///< refined if accepted, else the fallback (x, y, yaw)
    PoseEstimate estimate;               ///< the joint estimate, also when rejected (if it ran)

    int sample_points = 0;    ///< testable points (not OutOfImage), all references
    int inliers = 0;          ///< over all references
    double inlier_share = 0;  ///< inliers / sample_points (compared with N_th)
    double offset_m = 0;      ///< |refined - coarse (or nearest reference)| in x, y

    std::vector<ReferenceOutcome> references;
    StageTimes times;
};

class Refiner {
  public:
    /// Throws common::ConfigError when the options are invalid.
    explicit Refiner(RefinerOptions options = {});

    /// `references` are the candidates; `hint.reference_ids` picks among them (all if empty).
    /// `query_pyramid`: the query image's matching pyramid from queryPyramid(), when one frame
    /// is refined against many candidates (acquisition); built here when null.
    RefineResult refine(const mrpt::obs::CObservationImage& query, const CoarseHint& hint,
                        const std::vector<ReferenceImage>& references,
                        const std::shared_ptr<const ImagePyramid>& query_pyramid = nullptr) const;

    /// Same with a grey query image given directly (`camera_on_vehicle` as cameraPose).
    RefineResult refine(const cv::Mat& query_image, const mrpt::img::TCamera& query_camera,
                        const mrpt::poses::CPose3D& camera_on_vehicle, const CoarseHint& hint,
                        const std::vector<ReferenceImage>& references,
                        const std::shared_ptr<const ImagePyramid>& query_pyramid = nullptr) const;

    /// The matching pyramid refine() builds of a query image (the matcher's levels and
    /// preprocessing); empty for an empty or unreadable image.
    std::shared_ptr<const ImagePyramid> queryPyramid(const cv::Mat& query_image) const;
    std::shared_ptr<const ImagePyramid> queryPyramid(
        const mrpt::obs::CObservationImage& query) const;

    const RefinerOptions& options() const { return options_; }
    const AcceptancePolicy& acceptance() const { return acceptance_; }
    /// The query camera's readout as estimated while driving ([refine.rolling_shutter]).
    void setReadout(double readout_ms) { options_.rolling_shutter.readout_ms = readout_ms; }

  private:
    RefinerOptions options_;
    AcceptancePolicy acceptance_;
};

}  // namespace lookup::refine
