#include "lookup/refine/refiner.h"

#include <mrpt/img/CImage.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "lookup/refine/correspondence_methods.h"
#include "lookup/refine/matcher.h"
#include "lookup/refine/sampler.h"

namespace lookup::refine {

const char* toString(RefineStatus s) {
    switch (s) {
        case RefineStatus::Accepted:
            return "accepted";
        case RefineStatus::InvalidQuery:
            return "invalid query";
        case RefineStatus::NoReferences:
            return "no references";
        case RefineStatus::TooFewMatches:
            return "too few matches";
        case RefineStatus::LowInlierShare:
            return "low inlier share";
        case RefineStatus::OffsetTooLarge:
            return "offset too large";
        default:
            return "estimation failed";
    }
}

const char* toString(PoseSource s) {
    switch (s) {
        case PoseSource::Refined:
            return "refined";
        case PoseSource::Coarse:
            return "coarse";
        case PoseSource::Reference:
            return "reference";
        default:
            return "none";
    }
}

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// Why sample points did not become inliers, for the fallback reason: "(12 matched, 9 not
// distinctive, ...)". Points outside the image are left out, as from the inlier share.
std::string matchStatusSummary(const std::vector<ReferenceOutcome>& references) {
    constexpr MatchStatus kShown[] = {MatchStatus::Matched, MatchStatus::LowTexture,
                                      MatchStatus::NotDistinctive, MatchStatus::BorderPeak};
    std::string out;
    for (MatchStatus status : kShown) {
        int n = 0;
        for (const auto& ref : references)
            for (const auto& m : ref.matches) n += m.status == status ? 1 : 0;
        if (n == 0) continue;
        out += (out.empty() ? " (" : ", ") + std::to_string(n) + " " + toString(status);
    }
    return out.empty() ? out : out + ")";
}

/// The references the hint asks for whose intrinsics, image and heat map are usable.
struct UsableReferences {
    std::vector<const ReferenceImage*> refs;
    std::vector<Pinhole> cameras;  ///< of each of `refs`
    std::string skipped;           ///< why the others were left out
};

UsableReferences usableReferences(const std::vector<ReferenceImage>& references,
                                  const CoarseHint& hint, const SamplerOptions& sampler) {
    UsableReferences out;
    for (const ReferenceImage& r : references) {
        if (!hint.reference_ids.empty() &&
            std::find(hint.reference_ids.begin(), hint.reference_ids.end(), r.id) ==
                hint.reference_ids.end()) {
            continue;
        }
        Pinhole cam;
        std::string bad;
        const std::string which = " reference " + std::to_string(r.id) + ": ";
        if (!pinholeFrom(r.camera, cam, &bad)) {
            out.skipped += which + bad + ";";
        } else if (r.image.empty() || r.image.type() != CV_8UC1) {
            out.skipped += which + "image empty or not CV_8UC1;";
        } else if (!r.heat_map.empty() &&
                   !(r.sample_points && sameSelection(r.sample_points->options, sampler)) &&
                   (r.heat_map.type() != CV_32FC1 || r.heat_map.size() != r.image.size() ||
                    !cv::checkRange(r.heat_map))) {
            // (Checked only when the points are selected here: cached points were selected
            // from it already, and the scan cost 5 % of a heat-map localisation run.)
            out.skipped += which + "heat map not CV_32FC1 of the image size, or not finite;";
        } else {
            out.refs.push_back(&r);
            out.cameras.push_back(cam);
        }
    }
    return out;
}

/// What matching every reference needs of the query.
struct QueryView {
    const mrpt::img::TCamera* intrinsics = nullptr;  ///< as recorded (distortion included)
    Pinhole camera;
    mrpt::poses::CPose3D on_vehicle;
    std::optional<mrpt::poses::CPose3D> camera_in_map;  ///< at the coarse pose, if any
    double ceiling_height_m = 0;                        ///< prior of h
    RowTiming timing;                                   ///< its rolling shutter, if any
    int rows = 0;                                       ///< image height [px]
    ImagePyramid pyramid;
};

/// The plane-induced prediction from the coarse pose: either the reference-to-query
/// homography (motion-compensated matching) or each sample point's expected offset.
struct Prediction {
    std::optional<cv::Matx33d> reference_to_query;
    std::vector<cv::Point2f> offsets;  ///< one per sample point, or none (search around 0)
};

Prediction predict(const ReferenceImage& ref, const Pinhole& ref_cam,
                   const std::vector<cv::Point2f>& points, const QueryView& q,
                   const MatcherOptions& matcher) {
    Prediction p;
    if (!q.camera_in_map) return p;
    const double h = q.ceiling_height_m;
    if (matcher.compensate_motion) {
        p.reference_to_query =
            ceilingHomography(ref_cam, ref.cameraInMap(), q.camera, *q.camera_in_map, h);
        return p;
    }
    for (const auto& pt : points) {
        cv::Point2f offset(0.f, 0.f);
        if (const auto on_ceiling =
                backProjectToCeiling(ref_cam, ref.cameraInMap(), cv::Point2d(pt), h)) {
            if (const auto seen = projectToImage(q.camera, *q.camera_in_map, *on_ceiling)) {
                offset = cv::Point2f(float(seen->x - pt.x), float(seen->y - pt.y));
            }
        }
        p.offsets.push_back(offset);
    }
    return p;
}

/// SAD matches of the sample points `which` (indices into `points`).
std::vector<PointMatch> matchSad(const ImagePyramid& ref, const QueryView& q,
                                 const std::vector<cv::Point2f>& points, const Prediction& p,
                                 const std::vector<std::size_t>& which, const MatcherOptions& o) {
    std::vector<cv::Point2f> pts, offsets;
    for (std::size_t i : which) {
        pts.push_back(points[i]);
        if (!p.offsets.empty()) offsets.push_back(p.offsets[i]);
    }
    return p.reference_to_query
               ? matchPointsCompensated(ref, q.pyramid, pts, *p.reference_to_query, o)
               : matchPoints(ref, q.pyramid, pts, offsets, o);
}

/// Every (n / probe_points)-th sample point, then the rest: points run row by row, so the
/// probe spreads over the image. Returns why the probe failed, else matches them all.
std::optional<std::string> matchWithProbe(const ReferenceImage& ref,
                                          const ImagePyramid& ref_pyramid, const QueryView& q,
                                          const std::vector<cv::Point2f>& points,
                                          const Prediction& p, const CoarseHint& hint,
                                          const MatcherOptions& o,
                                          std::vector<PointMatch>& matches) {
    std::vector<std::size_t> probe, rest;
    const std::size_t n = points.size();
    const std::size_t n_probe = static_cast<std::size_t>(std::max(0, hint.probe_points));
    for (std::size_t i = 0; i < n; ++i) {
        const bool in_probe = n_probe > 0 && n_probe < n && (i * n_probe) % n < n_probe;
        (in_probe ? probe : rest).push_back(i);
    }
    matches.resize(n);
    int probe_matched = 0;
    if (!probe.empty()) {
        const auto m = matchSad(ref_pyramid, q, points, p, probe, o);
        for (std::size_t k = 0; k < probe.size(); ++k) {
            matches[probe[k]] = m[k];
            probe_matched += m[k].status == MatchStatus::Matched;
        }
        if (probe_matched < hint.probe_min_matched) {
            return "probe: " + std::to_string(probe_matched) + " of " +
                   std::to_string(probe.size()) + " probe points of reference " +
                   std::to_string(ref.id) + " matched (need " +
                   std::to_string(hint.probe_min_matched) + ")";
        }
    }
    const auto m = matchSad(ref_pyramid, q, points, p, rest, o);
    for (std::size_t k = 0; k < rest.size(); ++k) matches[rest[k]] = m[k];
    return std::nullopt;
}

/// The estimator's input before any view: the query stands on the floor its references stood
/// on and is tilted about as they were (their mean z and tilt, not the hint's: a coarse pose
/// is planar, z = 0 and level, while surveyed references carry the floor's bumps; the
/// difference would scale the query's view of the ceiling by up to 5 %).
EstimatorInput estimatorInput(const std::vector<const ReferenceImage*>& refs, const QueryView& q) {
    EstimatorInput input;
    input.query_camera = q.camera;
    input.query_camera_on_vehicle = q.on_vehicle;
    input.ceiling_height_m = q.ceiling_height_m;
    input.query_timing = q.timing;
    input.query_rows = q.rows;
    for (const ReferenceImage* r : refs) {
        input.vehicle_z += r->vehicle_in_map.z() / double(refs.size());
        input.prior_pitch_rad += r->vehicle_in_map.pitch() / double(refs.size());
        input.prior_roll_rad += r->vehicle_in_map.roll() / double(refs.size());
    }
    return input;
}

/// Counts the reference's testable sample points and inliers into `res` and gives its inliers,
/// rectified, to the estimator. Points whose window falls outside the query cannot be tested
/// and stay out of N_th's share.
void addInliers(const ReferenceOutcome& outcome, const ReferenceImage& ref, const Pinhole& ref_cam,
                const QueryView& q, RefineResult& res, EstimatorInput& input) {
    std::vector<cv::Point2f> ref_px, query_px;
    for (const auto& m : outcome.matches) {
        res.sample_points += m.status == MatchStatus::OutOfImage ? 0 : 1;
        if (!m.inlier) continue;
        ref_px.push_back(m.reference_px);
        query_px.push_back(m.query_px);
    }
    res.inliers += int(ref_px.size());
    if (ref_px.empty()) return;
    ReferenceView view;
    view.camera = ref_cam;
    view.camera_in_map = ref.cameraInMap();
    view.reference_px = undistortPixels(ref_px, ref.camera);
    view.query_px = undistortPixels(query_px, *q.intrinsics);
    view.timing = ref.timing;
    if (view.timing.rows == 0) view.timing.rows = ref.image.rows;
    view.camera_on_vehicle = ref.camera_on_vehicle;
    // Row times are the sensor's rows, before rectification; the query's also show a rolling
    // shutter the model does not carry (RowTravel).
    if (view.timing.active() || q.timing.active()) {
        for (const auto& p : ref_px) view.reference_row.push_back(p.y);
    }
    for (const auto& p : query_px) view.query_row.push_back(p.y);
    input.views.push_back(std::move(view));
}

/// |refined - coarse| in x, y, or to the nearest reference without a coarse pose.
double offsetFromHint(const mrpt::poses::CPose3D& refined, const CoarseHint& hint,
                      const std::vector<const ReferenceImage*>& refs) {
    if (hint.vehicle_pose) {
        return std::hypot(refined.x() - hint.vehicle_pose->x(),
                          refined.y() - hint.vehicle_pose->y());
    }
    double offset = std::numeric_limits<double>::max();
    for (const ReferenceImage* r : refs) {
        offset = std::min(offset, std::hypot(refined.x() - r->vehicle_in_map.x(),
                                             refined.y() - r->vehicle_in_map.y()));
    }
    return offset;
}

/// The pose reported when the refinement gives none: the coarse pose, else the first usable
/// reference's, with the acceptance policy's fallback covariance.
RefineResult fallBack(RefineResult res, RefineStatus status, std::string reason,
                      const CoarseHint& hint, const std::vector<const ReferenceImage*>& refs,
                      const AcceptancePolicy& acceptance, Clock::time_point t_start) {
    res.status = status;
    res.reason = std::move(reason);
    if (hint.vehicle_pose) {
        res.source = PoseSource::Coarse;
        res.pose = acceptance.fallback(mrpt::poses::CPose2D(*hint.vehicle_pose));
    } else if (!refs.empty()) {
        res.source = PoseSource::Reference;
        res.pose = acceptance.fallback(mrpt::poses::CPose2D(refs.front()->vehicle_in_map));
    } else {
        res.source = PoseSource::None;
        res.pose = acceptance.fallback(mrpt::poses::CPose2D());
        res.pose.cov *= 1e12;
    }
    res.times.total_ms = msSince(t_start);
    return res;
}

using Failure = std::pair<RefineStatus, std::string>;

/// The query's row times: with a readout configured and the vehicle's velocity in the hint.
RowTiming queryTiming(const CoarseHint& hint, int rows, const RollingShutterOptions& o) {
    RowTiming t;
    if (o.readout_ms <= 0.0 || !hint.vehicle_motion) return t;
    t.readout_s = 1e-3 * o.readout_ms;
    t.rows = rows;
    t.stamp_row = o.stampRow(rows);
    t.velocity = *hint.vehicle_motion;
    return t;
}

/// Why the query or the references cannot be refined at all; else completes `q` (camera,
/// ceiling height prior, camera pose at the coarse pose).
std::optional<Failure> unusableInput(const cv::Mat& image, const std::vector<ReferenceImage>& given,
                                     const UsableReferences& usable, const CoarseHint& hint,
                                     const EstimatorOptions& estimator,
                                     const RollingShutterOptions& rolling_shutter, QueryView& q) {
    std::string bad_query;
    if (!pinholeFrom(*q.intrinsics, q.camera, &bad_query)) {
        return Failure{RefineStatus::InvalidQuery, "query camera: " + bad_query};
    }
    if (image.empty() || (image.type() != CV_8UC1 && image.type() != CV_8UC3)) {
        return Failure{RefineStatus::InvalidQuery, "query image is empty or not 8-bit"};
    }
    if (usable.refs.empty()) {
        return Failure{RefineStatus::NoReferences,
                       given.empty()
                           ? "no references given"
                           : "none of the references is usable:" +
                                 (usable.skipped.empty() ? std::string(" no id matches the hint")
                                                         : usable.skipped)};
    }
    q.ceiling_height_m = hint.ceiling_height_m.value_or(estimator.ceiling_height_m);
    if (!std::isfinite(q.ceiling_height_m)) {
        return Failure{RefineStatus::InvalidQuery, "ceiling height prior is not finite"};
    }
    if (hint.vehicle_pose) q.camera_in_map = *hint.vehicle_pose + q.on_vehicle;
    q.rows = image.rows;
    q.timing = queryTiming(hint, image.rows, rolling_shutter);
    if (q.camera_in_map && q.timing.active()) {
        // The matcher's prediction from the middle row's pose: the rows' mean time.
        q.camera_in_map =
            q.timing.cameraAtRow(*q.camera_in_map, q.on_vehicle, 0.5 * (image.rows - 1));
    }
    return std::nullopt;
}

/// The illumination high-pass belongs to the SAD matcher; the OpenCV baselines see the images
/// as recorded (ECC's dense fit lost accuracy on the high-passed images).
MatcherOptions preprocessingFor(const RefinerOptions& o) {
    MatcherOptions preprocessing = o.matcher;
    if (o.correspondence.method != CorrespondenceMethod::Sad) {
        preprocessing.illumination_sigma_px = 0.0;
    }
    return preprocessing;
}

/// Sample points of `ref` matched into the query (SAD with the probe, or a baseline matcher)
/// and the reference's homography. Returns why the probe failed.
std::optional<std::string> matchReference(const ReferenceImage& ref, const Pinhole& ref_cam,
                                          const QueryView& q, const CoarseHint& hint,
                                          const RefinerOptions& o, ReferenceOutcome& outcome,
                                          StageTimes& times, std::string& matcher_notes) {
    outcome.id = ref.id;
    auto t0 = Clock::now();
    const MatcherOptions preprocessing = preprocessingFor(o);
    const int levels = effectivePyramidLevels(o.matcher);
    ImagePyramid local;
    const ImagePyramid* ref_pyramid = ref.pyramid.get();
    if (!ref_pyramid || int(ref_pyramid->levels.size()) <= levels ||
        !ref_pyramid->preprocessedFor(preprocessing)) {
        local = ImagePyramid::build(ref.image, levels, preprocessing);
        ref_pyramid = &local;
    }
    times.prepare_ms += msSince(t0);

    t0 = Clock::now();
    const bool cached = ref.sample_points && sameSelection(ref.sample_points->options, o.sampler);
    const std::vector<cv::Point2f> points =
        cached ? ref.sample_points->points
               : selectSamplePoints(ref.image.size(), ref.heat_map, o.sampler);
    const Prediction prediction = predict(ref, ref_cam, points, q, o.matcher);
    times.select_ms += msSince(t0);

    t0 = Clock::now();
    if (o.correspondence.method != CorrespondenceMethod::Sad) {
        std::optional<cv::Matx33d> H = prediction.reference_to_query;
        if (!H && q.camera_in_map) {
            H = ceilingHomography(ref_cam, ref.cameraInMap(), q.camera, *q.camera_in_map,
                                  q.ceiling_height_m);
        }
        CorrespondenceResult c =
            o.correspondence.method == CorrespondenceMethod::Orb
                ? matchOrb(ref_pyramid->levels[0], q.pyramid.levels[0], H, o.correspondence)
                : matchEcc(ref_pyramid->levels[0], q.pyramid.levels[0], points, H,
                           o.correspondence);
        outcome.matches = std::move(c.matches);
        if (!c.ok) matcher_notes += "; reference " + std::to_string(ref.id) + ": " + c.reason;
    } else if (auto why = matchWithProbe(ref, *ref_pyramid, q, points, prediction, hint, o.matcher,
                                         outcome.matches)) {
        times.match_ms += msSince(t0);
        return why;
    }
    times.match_ms += msSince(t0);

    t0 = Clock::now();
    const cv::Matx33d K_ref = ref_cam.K(), K_query = q.camera.K();
    outcome.homography = estimateHomography(outcome.matches, o.homography, &K_ref, &K_query);
    times.homography_ms += msSince(t0);
    return std::nullopt;
}

/// The joint estimate over every reference's inliers, then the acceptance policy.
RefineResult estimateAndAccept(RefineResult res, const EstimatorInput& input,
                               const CoarseHint& hint,
                               const std::vector<const ReferenceImage*>& refs,
                               const std::string& matcher_notes, const RefinerOptions& o,
                               const AcceptancePolicy& acceptance, Clock::time_point t_start) {
    const auto t0 = Clock::now();
    res.estimate = estimateQueryPose(input, o.estimator);
    res.times.estimate_ms += msSince(t0);

    const std::string counts = "inliers " + std::to_string(res.inliers) + " of " +
                               std::to_string(res.sample_points) + " sample points" +
                               matchStatusSummary(res.references);
    if (!res.estimate.ok) {
        const RefineStatus status = res.inliers < o.estimator.min_inliers
                                        ? RefineStatus::TooFewMatches
                                        : RefineStatus::EstimationFailed;
        std::string reason = counts + ": " + res.estimate.reason + matcher_notes;
        return fallBack(std::move(res), status, std::move(reason), hint, refs, acceptance, t_start);
    }
    res.offset_m = offsetFromHint(res.estimate.vehicle_in_map, hint, refs);
    if (auto rejection = acceptance.judge(res.inlier_share, res.offset_m,
                                          hint.vehicle_pose.has_value(), hint.tracked)) {
        std::string reason = rejection->status == RefineStatus::LowInlierShare
                                 ? counts + rejection->reason
                                 : rejection->reason;
        return fallBack(std::move(res), rejection->status, std::move(reason), hint, refs,
                        acceptance, t_start);
    }
    res.status = RefineStatus::Accepted;
    res.source = PoseSource::Refined;
    res.pose = res.estimate.pose;
    res.times.total_ms = msSince(t_start);
    return res;
}

}  // namespace

Refiner::Refiner(RefinerOptions options)
    : options_(std::move(options)), acceptance_(options_.acceptance) {
    options_.check();
}

namespace {

/// The pixels of `query` (an external image is loaded); empty with `why` when unreadable.
cv::Mat queryPixels(const mrpt::obs::CObservationImage& query, std::string& why) {
    try {
        return query.image.asCvMatRef();
    } catch (const std::exception& e) {
        why = e.what();
        return cv::Mat();
    }
}

}  // namespace

std::shared_ptr<const ImagePyramid> Refiner::queryPyramid(const cv::Mat& query_image) const {
    return std::make_shared<const ImagePyramid>(ImagePyramid::build(
        query_image, effectivePyramidLevels(options_.matcher), preprocessingFor(options_)));
}

std::shared_ptr<const ImagePyramid> Refiner::queryPyramid(
    const mrpt::obs::CObservationImage& query) const {
    std::string why;
    return queryPyramid(queryPixels(query, why));
}

RefineResult Refiner::refine(const mrpt::obs::CObservationImage& query, const CoarseHint& hint,
                             const std::vector<ReferenceImage>& references,
                             const std::shared_ptr<const ImagePyramid>& query_pyramid) const {
    std::string why;
    const cv::Mat image = queryPixels(query, why);
    if (image.empty()) {
        // Still decide the fallback pose from the hint: go through the common path.
        RefineResult r = refine(cv::Mat(), query.cameraParams, query.cameraPose, hint, references);
        r.reason = "query '" + query.sensorLabel + "': image not readable" +
                   (why.empty() ? std::string() : ": " + why);
        return r;
    }
    return refine(image, query.cameraParams, query.cameraPose, hint, references, query_pyramid);
}

namespace {

/// A planar pose and covariance from the floor's frame back into the map: the covariance turned
/// by the frame's heading (its shortening along a grade, cos of the slope, left out).
mrpt::poses::CPosePDFGaussian toMap(const mrpt::poses::CPosePDFGaussian& local,
                                    const mrpt::poses::CPose3D& floor) {
    mrpt::poses::CPosePDFGaussian in_map(
        mrpt::poses::CPose2D(floor + mrpt::poses::CPose3D(local.mean)), local.cov);
    in_map.rotateCov(floor.yaw());
    return in_map;
}

/// The refinement against `usable` (of the `references` given) with every pose in a frame whose
/// floor is level.
RefineResult refineOnLevelFloor(const Refiner& refiner, const cv::Mat& query_image,
                                const mrpt::img::TCamera& query_camera,
                                const mrpt::poses::CPose3D& camera_on_vehicle,
                                const CoarseHint& hint,
                                const std::vector<ReferenceImage>& references,
                                const UsableReferences& usable,
                                const std::shared_ptr<const ImagePyramid>& query_pyramid) {
    const RefinerOptions& o = refiner.options();
    const AcceptancePolicy& acceptance = refiner.acceptance();
    const auto t_start = Clock::now();
    RefineResult res;
    const auto fail = [&](RefineStatus status, std::string reason) {
        return fallBack(std::move(res), status, std::move(reason), hint, usable.refs, acceptance,
                        t_start);
    };
    QueryView q;
    q.intrinsics = &query_camera;
    q.on_vehicle = camera_on_vehicle;
    if (auto why = unusableInput(query_image, references, usable, hint, o.estimator,
                                 o.rolling_shutter, q)) {
        return fail(why->first, why->second);
    }
    auto t0 = Clock::now();
    q.pyramid = query_pyramid ? *query_pyramid : *refiner.queryPyramid(query_image);
    res.times.prepare_ms += msSince(t0);

    EstimatorInput input = estimatorInput(usable.refs, q);
    std::string matcher_notes;  // why a baseline matcher (orb, ecc) found nothing
    for (std::size_t k = 0; k < usable.refs.size(); ++k) {
        ReferenceOutcome outcome;
        if (auto why = matchReference(*usable.refs[k], usable.cameras[k], q, hint, o, outcome,
                                      res.times, matcher_notes)) {
            return fail(RefineStatus::TooFewMatches, *why);
        }
        addInliers(outcome, *usable.refs[k], usable.cameras[k], q, res, input);
        res.references.push_back(std::move(outcome));
    }
    res.inlier_share = res.sample_points > 0 ? double(res.inliers) / res.sample_points : 0.0;
    return estimateAndAccept(std::move(res), input, hint, usable.refs, matcher_notes, o, acceptance,
                             t_start);
}

}  // namespace

RefineResult Refiner::refine(const cv::Mat& query_image, const mrpt::img::TCamera& query_camera,
                             const mrpt::poses::CPose3D& camera_on_vehicle, const CoarseHint& hint,
                             const std::vector<ReferenceImage>& references,
                             const std::shared_ptr<const ImagePyramid>& query_pyramid) const {
    const UsableReferences usable = usableReferences(references, hint, options_.sampler);
    std::vector<mrpt::poses::CPose3D> vehicles;
    for (const ReferenceImage* r : usable.refs) vehicles.push_back(r->vehicle_in_map);
    const auto floor = floorFrame(vehicles);
    if (!floor) {
        return refineOnLevelFloor(*this, query_image, query_camera, camera_on_vehicle, hint,
                                  references, usable, query_pyramid);
    }
    std::vector<ReferenceImage> local;
    local.reserve(usable.refs.size());
    UsableReferences local_usable = usable;
    for (std::size_t k = 0; k < usable.refs.size(); ++k) {
        local.push_back(*usable.refs[k]);
        local.back().vehicle_in_map = inFloorFrame(local.back().vehicle_in_map, *floor);
        local_usable.refs[k] = &local.back();
    }
    CoarseHint local_hint = hint;
    if (hint.vehicle_pose) local_hint.vehicle_pose = inFloorFrame(*hint.vehicle_pose, *floor);
    RefineResult res = refineOnLevelFloor(*this, query_image, query_camera, camera_on_vehicle,
                                          local_hint, references, local_usable, query_pyramid);
    res.estimate.vehicle_in_map = *floor + res.estimate.vehicle_in_map;
    res.estimate.pose = toMap(res.estimate.pose, *floor);
    if (res.source == PoseSource::Refined) {
        res.pose = res.estimate.pose;
    } else if (res.source == PoseSource::Coarse) {
        res.pose = acceptance_.fallback(mrpt::poses::CPose2D(*hint.vehicle_pose));
    } else if (res.source == PoseSource::Reference) {
        res.pose = acceptance_.fallback(mrpt::poses::CPose2D(usable.refs.front()->vehicle_in_map));
    }
    return res;
}

}  // namespace lookup::refine
