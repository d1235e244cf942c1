#pragma once
// Global acquisition's candidate places: one query ceiling frame against the database's place
// index, the candidates turned into vehicle poses and merged into distinct places. The
// localiser verifies them with the SAD refinement (Localizer::acquireGlobally).

#include <mrpt/obs/CObservationImage.h>
#include <mrpt/poses/CPose2D.h>

#include <string>
#include <vector>

namespace lookup::database {
class ReferenceDatabase;
}
namespace lookup::place {
class PlaceIndex;
}

namespace lookup::localize {

struct CandidatePlace {
    mrpt::poses::CPose2D vehicle_pose;  ///< query vehicle pose the best candidate implies
    std::size_t reference = 0;          ///< that candidate's reference
    int inliers = 0;                    ///< its geometric inliers
};

struct PlaceSearchResult {
    std::vector<CandidatePlace> places;  ///< distinct places, most inliers first
    double ms = 0;
    int features = 0;  ///< features found in the query image
};

/// Up to `max_places` places at least `separation_m` apart that explain `query`.
PlaceSearchResult searchPlaces(const place::PlaceIndex& index,
                               const database::ReferenceDatabase& db,
                               const mrpt::obs::CObservationImage& query, std::size_t max_places,
                               double separation_m);

}  // namespace lookup::localize
