#pragma once
// From a place candidate (a pixel transform between the query and one reference image) to the
// query vehicle's pose in the map, through the ceiling plane.

#include <mrpt/img/TCamera.h>
#include <mrpt/poses/CPose2D.h>
#include <mrpt/poses/CPose3D.h>

#include <optional>
#include <vector>

#include "lookup/place/place_index.h"

namespace lookup::database {
class ReferenceDatabase;
}

namespace lookup::place {

struct QueryCamera {
    mrpt::img::TCamera intrinsics;    ///< of the query image (rectified pinhole)
    mrpt::poses::CPose3D on_vehicle;  ///< CObservationImage::cameraPose
};

/// The vehicle pose the candidate implies: a few query pixels map through the transform into
/// the reference image; both sets are back-projected onto the ceiling plane z = h (the
/// reference camera where the survey put it, the query camera on a vehicle at the origin), and
/// the planar rigid motion between the two point sets is the query vehicle's pose; a reference
/// with a 3-D pose (a grade) in its floor's frame (refine::floorFrame), the plane h above its
/// floor. Empty when the rays miss the plane, the intrinsics are unusable, or the two point
/// sets' sizes differ by more than `max_scale_change` (PlaceIndexOptions): no camera height
/// explains the transform.
std::optional<mrpt::poses::CPose2D> vehiclePose(const PlaceCandidate& candidate,
                                                const mrpt::img::TCamera& reference_camera,
                                                const mrpt::poses::CPose3D& reference_vehicle,
                                                const mrpt::poses::CPose3D& reference_mount,
                                                const QueryCamera& query, double ceiling_height_m,
                                                double max_scale_change);

/// How much larger `db`'s references show the ceiling than the query camera does, in pixels:
/// the cameras' distances to the ceiling (the query vehicle on a reference's floor) and their
/// focal lengths. 1 where a camera is unusable or not below the ceiling.
double expectedPixelScale(const database::ReferenceDatabase& db, const QueryCamera& query);

/// The same for a candidate of `db`'s index: its reference's pose and mount, the database's
/// ceiling height, and the reference camera the index was built in (the ideal pinhole twin of
/// db.ini's; `query.intrinsics` must be of a rectified query likewise).
std::optional<mrpt::poses::CPose2D> vehiclePose(const PlaceCandidate& candidate,
                                                const database::ReferenceDatabase& db,
                                                const QueryCamera& query, double max_scale_change);

/// A candidate of the index with the vehicle pose it implies.
struct PlacedCandidate {
    PlaceCandidate candidate;
    mrpt::poses::CPose2D vehicle_pose;
};

/// The index's candidates for one rectified grey query image that imply a vehicle pose, most
/// inliers first: the query detected at the references' scale (expectedPixelScale), each
/// candidate judged in metres (vehiclePose with the index's max_scale_change).
std::vector<PlacedCandidate> placeQuery(const PlaceIndex& index,
                                        const database::ReferenceDatabase& db,
                                        const QueryCamera& query, const cv::Mat& grey,
                                        PlaceQueryTimes* times = nullptr);

}  // namespace lookup::place
