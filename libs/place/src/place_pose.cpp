#include "lookup/place/place_pose.h"

#include <cmath>
#include <vector>

#include "lookup/database/reference_database.h"
#include "lookup/refine/geometry.h"
#include "lookup/refine/rectifier.h"

namespace lookup::place {

namespace {

std::optional<mrpt::poses::CPose2D> onLevelFloor(const PlaceCandidate& candidate,
                                                 const mrpt::img::TCamera& reference_camera,
                                                 const mrpt::poses::CPose3D& reference_vehicle,
                                                 const mrpt::poses::CPose3D& reference_mount,
                                                 const QueryCamera& query, double h,
                                                 double max_scale_change) {
    refine::Pinhole ref_cam, query_cam;
    if (!refine::pinholeFrom(reference_camera, ref_cam, nullptr) ||
        !refine::pinholeFrom(query.intrinsics, query_cam, nullptr)) {
        return std::nullopt;
    }
    const mrpt::poses::CPose3D ref_in_map = reference_vehicle + reference_mount;
    // The query vehicle at the origin, on the reference's floor height.
    const mrpt::poses::CPose3D query_in_vehicle =
        mrpt::poses::CPose3D(0, 0, reference_vehicle.z(), 0, 0, 0) + query.on_vehicle;
    // The four quarter points and the centre of the query image.
    const double w = query.intrinsics.ncols, hgt = query.intrinsics.nrows;
    std::vector<cv::Point2d> in_vehicle, in_map;
    for (const auto& [u, v] :
         {std::pair{0.5, 0.5}, {0.25, 0.25}, {0.75, 0.25}, {0.25, 0.75}, {0.75, 0.75}}) {
        const cv::Point2d q(u * w, v * hgt);
        const cv::Matx23d& A = candidate.query_to_reference;
        const cv::Point2d r(A(0, 0) * q.x + A(0, 1) * q.y + A(0, 2),
                            A(1, 0) * q.x + A(1, 1) * q.y + A(1, 2));
        const auto a = refine::backProjectToCeiling(query_cam, query_in_vehicle, q, h);
        const auto b = refine::backProjectToCeiling(ref_cam, ref_in_map, r, h);
        if (!a || !b) return std::nullopt;
        in_vehicle.emplace_back(a->x, a->y);
        in_map.emplace_back(b->x, b->y);
    }
    // Planar Procrustes: the rotation and translation taking vehicle-frame points to map ones.
    cv::Point2d ca(0, 0), cb(0, 0);
    for (std::size_t i = 0; i < in_vehicle.size(); ++i) {
        ca += in_vehicle[i];
        cb += in_map[i];
    }
    ca /= double(in_vehicle.size());
    cb /= double(in_map.size());
    double s_cos = 0, s_sin = 0, spread_a = 0, spread_b = 0;
    for (std::size_t i = 0; i < in_vehicle.size(); ++i) {
        const cv::Point2d a = in_vehicle[i] - ca, b = in_map[i] - cb;
        s_cos += a.x * b.x + a.y * b.y;
        s_sin += a.x * b.y - a.y * b.x;
        spread_a += a.dot(a);
        spread_b += b.dot(b);
    }
    // One ceiling seen by both: the same size in metres, whatever each camera's height.
    if (!(std::abs(std::sqrt(spread_b / spread_a) - 1) <= max_scale_change)) return std::nullopt;
    const double yaw = std::atan2(s_sin, s_cos);
    const double c = std::cos(yaw), s = std::sin(yaw);
    const double x = cb.x - (c * ca.x - s * ca.y), y = cb.y - (s * ca.x + c * ca.y);
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(yaw)) return std::nullopt;
    return mrpt::poses::CPose2D(x, y, yaw);
}

}  // namespace

std::optional<mrpt::poses::CPose2D> vehiclePose(const PlaceCandidate& candidate,
                                                const mrpt::img::TCamera& reference_camera,
                                                const mrpt::poses::CPose3D& reference_vehicle,
                                                const mrpt::poses::CPose3D& reference_mount,
                                                const QueryCamera& query, double h,
                                                double max_scale_change) {
    // A reference with a 3-D pose on a grade sees its ceiling parallel to its floor.
    const auto floor = refine::floorFrame({reference_vehicle});
    if (!floor) {
        return onLevelFloor(candidate, reference_camera, reference_vehicle, reference_mount, query,
                            h, max_scale_change);
    }
    const auto local =
        onLevelFloor(candidate, reference_camera, refine::inFloorFrame(reference_vehicle, *floor),
                     reference_mount, query, h, max_scale_change);
    if (!local) return std::nullopt;
    return mrpt::poses::CPose2D(*floor + mrpt::poses::CPose3D(*local));
}

double expectedPixelScale(const database::ReferenceDatabase& db, const QueryCamera& query) {
    if (db.size() == 0) return 1.0;
    // The first reference's mount, the survey's: a refresh may add another vehicle's, whose
    // candidates are still judged in metres by their own mount (vehiclePose).
    const double h = db.info().ceiling_height_m;
    const double to_reference = h - db.reference(0).ceiling_camera_mount.z();
    const double to_query = h - query.on_vehicle.z();
    refine::Pinhole ref_cam, query_cam;
    if (!refine::pinholeFrom(refine::idealPinhole(db.info().ceiling_camera), ref_cam, nullptr) ||
        !refine::pinholeFrom(query.intrinsics, query_cam, nullptr) || !(to_reference > 0) ||
        !(to_query > 0)) {
        return 1.0;
    }
    return (to_query / to_reference) * (ref_cam.fx / query_cam.fx);
}

std::optional<mrpt::poses::CPose2D> vehiclePose(const PlaceCandidate& candidate,
                                                const database::ReferenceDatabase& db,
                                                const QueryCamera& query, double max_scale_change) {
    const auto& ref = db.reference(candidate.reference);
    return vehiclePose(candidate, refine::idealPinhole(db.info().ceiling_camera), ref.vehicle_pose,
                       ref.ceiling_camera_mount, query, db.info().ceiling_height_m,
                       max_scale_change);
}

std::vector<PlacedCandidate> placeQuery(const PlaceIndex& index,
                                        const database::ReferenceDatabase& db,
                                        const QueryCamera& query, const cv::Mat& grey,
                                        PlaceQueryTimes* times) {
    std::vector<PlacedCandidate> out;
    for (const auto& c : index.query(grey, times, expectedPixelScale(db, query))) {
        if (auto pose = vehiclePose(c, db, query, index.options().max_scale_change)) {
            out.push_back({c, *pose});
        }
    }
    return out;
}

}  // namespace lookup::place
