#pragma once
// The survey's own ceiling height (the paper's pixel-to-metre problem): the camera-to-ceiling
// distance is not given to the survey; it follows from ceiling images taken a known laser /
// odometry baseline apart. For frames sampled along each traverse, frame j is refined against
// its neighbours a baseline behind and ahead (their laser poses known) by the localiser's own
// estimator (lookup::refine), which fits the query pose and the ceiling plane height h
// jointly from a weak prior; the accepted estimates' median is the database's h.
//
// h is the refiner's: the ceiling plane above the vehicle base (map z = 0), so the camera-to-
// ceiling distance is h minus the camera mount's z (reported as well).

#include <mrpt/obs/CObservationImage.h>
#include <mrpt/poses/CPose3DInterpolator.h>

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "lookup/survey/survey_options.h"

namespace lookup::survey {

/// One traverse's ceiling images with the laser-derived vehicle pose track they are placed by.
struct CeilingTraverse {
    std::string name;
    const std::vector<mrpt::obs::CObservationImage::Ptr>* ceiling = nullptr;  ///< time order
    const mrpt::poses::CPose3DInterpolator* poses = nullptr;
};

struct CeilingDistanceEstimate {
    bool estimated = false;          ///< false: too few accepted triples, `prior_m` used
    double ceiling_height_m = 0;     ///< the value the database gets [m]
    double prior_m = 0;              ///< the configured prior it started from [m]
    double spread_m = 0;             ///< 1.4826 x median absolute deviation of the accepted [m]
    double camera_to_ceiling_m = 0;  ///< ceiling_height_m - the camera mount's z [m]
    double camera_z_m = 0;           ///< camera mount height above the vehicle base [m]
    std::size_t tried = 0;           ///< triples refined
    std::size_t used = 0;            ///< accepted and within 3 spreads of the median
    std::size_t rejected = 0;        ///< refused by the refiner, or outliers
    std::string warning;             ///< set when not estimated (also a survey warning)
    double time_s = 0;               ///< wall time of the estimate [s]
};

/// Estimates h from the traverses' images (options: ceiling_* of SurveyOptions). Never
/// throws for bad images: an unreadable triple is counted as rejected.
CeilingDistanceEstimate estimateCeilingDistance(const std::vector<CeilingTraverse>& traverses,
                                                const SurveyOptions& options);

/// survey_report.json's "ceiling" object.
nlohmann::ordered_json ceilingJson(const CeilingDistanceEstimate& e, const std::string& source);

}  // namespace lookup::survey
