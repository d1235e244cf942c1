#include "lookup/localize/readout_estimator.h"

#include <cmath>

#include "robust_fit.h"

namespace lookup::localize {

namespace {
// Two readouts from fewer frames would be a guess; reported from here on, applied from
// ReadoutEstimatorOptions::min_frames.
constexpr std::size_t kMinFramesToReport = 10;
}  // namespace

ReadoutEstimator::ReadoutEstimator(const ReadoutEstimatorOptions& options,
                                   double configured_query_s, double configured_survey_s)
    : options_(options),
      query_configured_(configured_query_s > 0),
      survey_configured_(configured_survey_s > 0),
      query_s_(configured_query_s),
      survey_s_(configured_survey_s) {}

void ReadoutEstimator::addFrame(double query_speed_mps, double survey_speed_mps,
                                const refine::RowTravel& rows) {
    if (!options_.enabled ||
        !std::isfinite(query_speed_mps + survey_speed_mps + rows.travel_m + rows.sigma_m)) {
        return;
    }
    // What the rows would show with no readout modelled: add back what the model carried.
    const double travel = rows.travel_m + query_s_ * query_speed_mps - survey_s_ * survey_speed_mps;
    frames_.push_back({query_speed_mps, survey_speed_mps, travel});
    if (frames_.size() > options_.max_frames) frames_.pop_front();
    refit();
}

void ReadoutEstimator::refit() {
    if (frames_.size() < kMinFramesToReport) return;
    // travel = query readout x query speed - survey readout x survey speed.
    const auto fit = detail::robustFit(
        frames_, [](const Frame& f) { return f.query_speed; },
        [](const Frame& f) { return -f.survey_speed; }, [](const Frame& f) { return f.travel; });
    if (!fit) return;  // the speeds never varied apart: nothing to see
    estimate_ =
        Estimate{fit->slope, fit->sigma, fit->nuisance, fit->nuisance_sigma, frames_.size()};
    if (!options_.apply || frames_.size() < options_.min_frames) return;
    // One camera's readout modelled and the other's left out undoes the cancellation of two
    // alike: each is applied alone only where the other is bounded to under half of it (then
    // modelling it leaves less error than not), or with the other where both are applicable.
    const bool query = applicable(fit->slope, fit->sigma);
    const bool survey = options_.apply_survey && applicable(fit->nuisance, fit->nuisance_sigma);
    const bool query_known = query_configured_ || query_applied_ || query;
    const bool survey_known = survey_configured_ || survey_applied_ || survey;
    if (!query_configured_ && query &&
        (survey_known || under(fit->nuisance, fit->nuisance_sigma, 0.5 * fit->slope))) {
        query_s_ = fit->slope;
        query_applied_ = true;
    }
    if (!survey_configured_ && survey &&
        (query_known || under(fit->slope, fit->sigma, 0.5 * fit->nuisance))) {
        survey_s_ = fit->nuisance;
        survey_applied_ = true;
    }
}

bool ReadoutEstimator::under(double readout_s, double sigma_s, double bound_s) const {
    return std::abs(readout_s) + options_.significance * sigma_s <= bound_s;
}

bool ReadoutEstimator::applicable(double readout_s, double sigma_s) const {
    return sigma_s <= options_.max_sigma_s && readout_s > options_.significance * sigma_s &&
           readout_s >= options_.min_readout_s && readout_s < options_.max_readout_s;
}

}  // namespace lookup::localize
