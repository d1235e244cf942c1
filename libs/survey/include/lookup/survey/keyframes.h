#pragma once
// Keyframe selection along a traverse (paper Sec. III-A: references every ~0.25 m of travel).

#include <mrpt/poses/CPose3D.h>

#include <functional>
#include <vector>

#include "lookup/survey/image_quality.h"
#include "lookup/survey/survey_options.h"

namespace lookup::survey {

/// One candidate ceiling frame, in time order.
struct KeyframeCandidate {
    double time_s = 0;
    mrpt::poses::CPose3D vehicle_pose;  ///< map frame
};

struct KeyframeSelection {
    std::vector<std::size_t> kept;           ///< indices into the candidates, increasing
    std::vector<ImageQuality> kept_quality;  ///< quality of each kept frame
    std::vector<double> kept_travelled_m;    ///< distance travelled at each kept frame [m]
    std::size_t rejected_blur = 0;           ///< candidates skipped as blurred
    std::size_t rejected_exposure = 0;       ///< candidates skipped as badly exposed
    std::size_t rejected_unusable = 0;       ///< candidates whose image is not usable
};

/// Keeps the first good frame, then the first good frame after each further
/// `keyframe_spacing_m` of travel (path length of the vehicle positions). A frame due for
/// keeping but unusable (ImageQuality::usable false), blurred or badly exposed is skipped and the
/// next good one is taken. `quality` is called only on frames due for keeping (it loads the image).
KeyframeSelection selectKeyframes(const std::vector<KeyframeCandidate>& candidates,
                                  const SurveyOptions& options,
                                  const std::function<ImageQuality(std::size_t)>& quality);

}  // namespace lookup::survey
