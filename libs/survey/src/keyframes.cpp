#include "lookup/survey/keyframes.h"

#include <cmath>

namespace lookup::survey {

KeyframeSelection selectKeyframes(const std::vector<KeyframeCandidate>& candidates,
                                  const SurveyOptions& options,
                                  const std::function<ImageQuality(std::size_t)>& quality) {
    KeyframeSelection out;
    double travelled = 0;
    double last_kept_at = -1e300;  // so the first good frame is kept
    for (std::size_t i = 0; i < candidates.size(); ++i) {
        if (i > 0) {
            const auto& a = candidates[i - 1].vehicle_pose;
            const auto& b = candidates[i].vehicle_pose;
            travelled += std::hypot(b.x() - a.x(), b.y() - a.y());
        }
        if (travelled - last_kept_at < options.keyframe_spacing_m) continue;
        const ImageQuality q = quality(i);
        if (!q.usable) {
            ++out.rejected_unusable;
            continue;
        }
        if (q.sharpness < options.min_sharpness) {
            ++out.rejected_blur;
            continue;
        }
        if (q.mean_intensity < options.min_mean_intensity ||
            q.mean_intensity > options.max_mean_intensity ||
            q.clipped_fraction > options.max_clipped_fraction) {
            ++out.rejected_exposure;
            continue;
        }
        out.kept.push_back(i);
        out.kept_quality.push_back(q);
        out.kept_travelled_m.push_back(travelled);
        last_kept_at = travelled;
    }
    return out;
}

}  // namespace lookup::survey
