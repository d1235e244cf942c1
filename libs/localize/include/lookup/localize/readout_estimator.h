#pragma once
// The ceiling cameras' rolling-shutter readout, estimated from the drive itself.
//
// A camera that reads its rows one after another while the vehicle moves sees the ceiling
// stretched (or sheared) along the drive: each refined frame's residuals show the vehicle's
// travel from the first row to the last that the estimator's model does not carry
// (refine::RowTravel). That travel is the query camera's readout times the vehicle's speed,
// less the survey camera's readout times the speed the survey vehicle had under the
// references (their images are stretched alike, so equal speeds cancel). Fitted over the
// frames, both readouts are observable where the two speeds vary apart: accelerating,
// braking, driving at another speed than the survey.
//
// A readout not configured ([refine.rolling_shutter] readout_ms, the database's
// ceiling_readout_ms) is applied, where ReadoutEstimatorOptions::apply says, once its estimate
// is precise and significant: unmodelled, a 30 ms readout at 40 km/h puts every pose 0.17 m
// along the drive (the rows' mean exposure lies half a readout after the first row's stamp).
// A configured readout is kept, and the estimate only reported.

#include <cstddef>
#include <deque>
#include <optional>

#include "lookup/refine/estimator.h"

namespace lookup::localize {

struct ReadoutEstimatorOptions {
    bool enabled = true;  ///< estimate (and report)
    bool apply = true;    ///< apply an estimate to a readout not configured
    /// Apply the survey camera's too. Where the survey's camera clock is unknown its lateness
    /// and its half readout are one unknown shift of the references, which a vehicle's camera
    /// alike cancels: its readout is then left alone, and the vehicle's applied only where the
    /// survey's is configured or bounded to under half of it.
    bool apply_survey = true;
    std::size_t min_frames = 40;    ///< before anything is applied
    std::size_t max_frames = 1000;  ///< the newest kept (the cameras' readouts are fixed)
    double max_sigma_s = 0.003;     ///< an estimate more uncertain is not applied [s]
    double significance = 3.0;      ///< nor one within this many sigmas of zero
    /// Nor one shorter: on global shutters the rows' travel strays by several ms of readout
    /// while the fit settles [s].
    double min_readout_s = 0.010;
    double max_readout_s = 0.1;  ///< nor one longer (not a readout) [s]
};

class ReadoutEstimator {
  public:
    struct Estimate {
        double query_s = 0, query_sigma_s = 0;    ///< this vehicle's ceiling camera [s]
        double survey_s = 0, survey_sigma_s = 0;  ///< the survey's ceiling camera [s]
        std::size_t frames = 0;
    };

    /// `configured_*_s`: the readouts configured (0 = not: a global shutter or unknown).
    ReadoutEstimator(const ReadoutEstimatorOptions& options, double configured_query_s,
                     double configured_survey_s);

    /// A refined frame: the vehicle's speed along its heading, the survey vehicle's under the
    /// frame's references (signed, each in its own frame), and what the frame's rows showed
    /// with the readouts applied then. Refits; then applies what has become precise and
    /// significant, or follows an applied estimate.
    void addFrame(double query_speed_mps, double survey_speed_mps, const refine::RowTravel& rows);

    /// The latest fit (from a few frames on).
    const std::optional<Estimate>& estimate() const { return estimate_; }
    /// The readouts the localiser models now: configured, estimated and applied, or 0 [s].
    double queryReadout() const { return query_s_; }
    double surveyReadout() const { return survey_s_; }
    bool queryApplied() const { return query_applied_; }
    bool surveyApplied() const { return survey_applied_; }
    /// Whether an estimate will be applied once precise and significant.
    bool applies() const { return options_.enabled && options_.apply; }
    bool appliesSurvey() const { return applies() && options_.apply_survey; }

    /// What is modelled now, to tell what a frame changed.
    struct Modelled {
        double query_s = 0, survey_s = 0;
        bool query_applied = false, survey_applied = false;
    };
    Modelled modelled() const { return {query_s_, survey_s_, query_applied_, survey_applied_}; }

  private:
    struct Frame {
        double query_speed = 0, survey_speed = 0;
        double travel = 0;  ///< the rows' travel with no readout modelled [m]
    };
    void refit();
    /// Whether an estimate lies within `bound_s` of zero by `significance` sigmas (either
    /// sign: a small negative one is the rows' other stretch, not a readout).
    bool under(double readout_s, double sigma_s, double bound_s) const;
    /// Whether an estimate is precise, significant and a readout (positive, not too long).
    bool applicable(double readout_s, double sigma_s) const;

    ReadoutEstimatorOptions options_;
    bool query_configured_, survey_configured_;
    double query_s_, survey_s_;
    bool query_applied_ = false, survey_applied_ = false;
    std::deque<Frame> frames_;
    std::optional<Estimate> estimate_;
};

}  // namespace lookup::localize
