#include "lookup/localize/place_search.h"

#include <mrpt/system/CTicTac.h>

#include <cmath>

#include "lookup/common/grey.h"
#include "lookup/database/reference_database.h"
#include "lookup/place/place_index.h"
#include "lookup/place/place_pose.h"

namespace lookup::localize {

namespace {

cv::Mat greyOf(const mrpt::img::CImage& image) {
    if (image.isExternallyStored()) image.forceLoad();
    return common::greyOf(image.asCvMat<cv::Mat>(mrpt::img::SHALLOW_COPY));
}

}  // namespace

PlaceSearchResult searchPlaces(const place::PlaceIndex& index,
                               const database::ReferenceDatabase& db,
                               const mrpt::obs::CObservationImage& query, std::size_t max_places,
                               double separation_m) {
    mrpt::system::CTicTac timer;
    PlaceSearchResult out;
    place::PlaceQueryTimes times;
    // The query is rectified (Localizer::process), as the indexed references were.
    const place::QueryCamera camera{query.cameraParams, query.cameraPose};
    const auto candidates = place::placeQuery(index, db, camera, greyOf(query.image), &times);
    out.features = times.query_features;
    for (const auto& [c, pose] : candidates) {
        if (out.places.size() >= max_places) break;
        // Candidates come most inliers first: a later one near a kept place is the same place.
        bool known = false;
        for (const auto& p : out.places) {
            known = known || std::hypot(p.vehicle_pose.x() - pose.x(),
                                        p.vehicle_pose.y() - pose.y()) < separation_m;
        }
        if (!known) out.places.push_back({pose, c.reference, c.inliers});
    }
    out.ms = 1e3 * timer.Tac();
    return out;
}

}  // namespace lookup::localize
