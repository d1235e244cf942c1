#include "lookup/refine/refiner.h"

#include <mrpt/img/CImage.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
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

// Rectified pixels for the estimator (matching runs on the raw images).
std::vector<cv::Point2d> rectify(const std::vector<cv::Point2f>& px,
                                 const mrpt::img::TCamera& camera, const Pinhole& pinhole) {
    std::vector<cv::Point2d> out(px.begin(), px.end());
    if (px.empty() || !hasDistortion(camera)) return out;
    const cv::Mat K(pinhole.K());
    std::vector<cv::Point2f> undistorted;
    if (camera.distortion == mrpt::img::DistortionModel::kannala_brandt) {
        const cv::Vec4d d(camera.k1(), camera.k2(), camera.k3(), camera.k4());
        cv::fisheye::undistortPoints(px, undistorted, K, d, cv::noArray(), K);
    } else {
        const std::vector<double> d(camera.dist.begin(), camera.dist.end());
        cv::undistortPoints(px, undistorted, K, d, cv::noArray(), K);
    }
    return {undistorted.begin(), undistorted.end()};
}

}  // namespace

Refiner::Refiner(RefinerOptions options) : options_(std::move(options)) { options_.check(); }

RefineResult Refiner::refine(const mrpt::obs::CObservationImage& query, const CoarseHint& hint,
                             const std::vector<Reference>& references) const {
    cv::Mat image;
    std::string why;
    try {
        image = query.image.asCvMatRef();  // loads an external image
    } catch (const std::exception& e) {
        why = e.what();
    }
    if (image.empty()) {
        // Still decide the fallback pose from the hint: go through the common path.
        RefineResult r = refine(cv::Mat(), query.cameraParams, query.cameraPose, hint, references);
        r.reason = "query '" + query.sensorLabel + "': image not readable" +
                   (why.empty() ? std::string() : ": " + why);
        return r;
    }
    return refine(image, query.cameraParams, query.cameraPose, hint, references);
}

RefineResult Refiner::refine(const cv::Mat& query_image, const mrpt::img::TCamera& query_camera,
                             const mrpt::poses::CPose3D& camera_on_vehicle, const CoarseHint& hint,
                             const std::vector<Reference>& references) const {
    const auto t_start = Clock::now();
    const RefinerOptions& o = options_;
    RefineResult res;

    // References the hint asks for, with valid intrinsics and images.
    std::vector<const Reference*> refs;
    std::vector<Pinhole> ref_cams;
    std::string skipped;
    std::string matcher_notes;  // why a baseline matcher (orb, ecc) found nothing
    for (const Reference& r : references) {
        if (!hint.reference_ids.empty() &&
            std::find(hint.reference_ids.begin(), hint.reference_ids.end(), r.id) ==
                hint.reference_ids.end()) {
            continue;
        }
        Pinhole cam;
        std::string bad;
        if (!pinholeFrom(r.camera, cam, &bad)) {
            skipped += " reference " + std::to_string(r.id) + ": " + bad + ";";
        } else if (r.image.empty() || r.image.type() != CV_8UC1) {
            skipped += " reference " + std::to_string(r.id) + ": image empty or not CV_8UC1;";
        } else if (!r.heat_map.empty() &&
                   !(r.sample_points && sameSelection(r.sample_points->options, o.sampler)) &&
                   (r.heat_map.type() != CV_32FC1 || r.heat_map.size() != r.image.size() ||
                    !cv::checkRange(r.heat_map))) {
            // (Checked only when the points are selected here: cached points were selected
            // from it already, and the scan cost 5 % of a heat-map localisation run.)
            skipped += " reference " + std::to_string(r.id) +
                       ": heat map not CV_32FC1 of the image size, or not finite;";
        } else {
            refs.push_back(&r);
            ref_cams.push_back(cam);
        }
    }

    // Fallback pose: the coarse pose, else the first usable (or hinted) reference.
    const auto fallback = [&](RefineStatus status, std::string reason) {
        res.status = status;
        res.reason = std::move(reason);
        const double s_xy = o.acceptance.fallback_sigma_xy_m;
        const double s_yaw = o.acceptance.fallback_sigma_yaw_deg * M_PI / 180.0;
        mrpt::math::CMatrixDouble33 cov;
        cov.setZero();
        cov(0, 0) = cov(1, 1) = s_xy * s_xy;
        cov(2, 2) = s_yaw * s_yaw;
        if (hint.vehicle_pose) {
            res.source = PoseSource::Coarse;
            res.pose = mrpt::poses::CPosePDFGaussian(mrpt::poses::CPose2D(*hint.vehicle_pose), cov);
        } else if (!refs.empty()) {
            res.source = PoseSource::Reference;
            res.pose = mrpt::poses::CPosePDFGaussian(
                mrpt::poses::CPose2D(refs.front()->vehicle_in_map), cov);
        } else {
            res.source = PoseSource::None;
            cov *= 1e12;
            res.pose = mrpt::poses::CPosePDFGaussian(mrpt::poses::CPose2D(), cov);
        }
        res.times.total_ms = msSince(t_start);
        return res;
    };

    Pinhole query_cam;
    std::string bad_query;
    if (!pinholeFrom(query_camera, query_cam, &bad_query)) {
        return fallback(RefineStatus::InvalidQuery, "query camera: " + bad_query);
    }
    if (query_image.empty() || (query_image.type() != CV_8UC1 && query_image.type() != CV_8UC3)) {
        return fallback(RefineStatus::InvalidQuery, "query image is empty or not 8-bit");
    }
    if (refs.empty()) {
        return fallback(
            RefineStatus::NoReferences,
            references.empty()
                ? "no references given"
                : "none of the references is usable:" +
                      (skipped.empty() ? std::string(" no id matches the hint") : skipped));
    }

    const double h0 = hint.ceiling_height_m.value_or(o.estimator.ceiling_height_m);
    if (!std::isfinite(h0))
        return fallback(RefineStatus::InvalidQuery, "ceiling height prior is not finite");
    const int levels = effectivePyramidLevels(o.matcher);
    auto t0 = Clock::now();
    // The illumination high-pass belongs to the SAD matcher; the OpenCV baselines see the
    // images as before (ECC's dense fit lost accuracy on the high-passed images).
    MatcherOptions preprocessing = o.matcher;
    if (o.correspondence.method != CorrespondenceMethod::Sad) {
        preprocessing.illumination_sigma_px = 0.0;
    }
    const ImagePyramid query_pyramid = ImagePyramid::build(query_image, levels, preprocessing);
    res.times.prepare_ms += msSince(t0);

    EstimatorInput input;
    input.query_camera = query_cam;
    input.query_camera_on_vehicle = camera_on_vehicle;
    input.ceiling_height_m = h0;
    // The query stands on the floor its references stood on, and is tilted about as they were:
    // their mean z and tilt, not the hint's (a coarse pose is planar, z = 0 and level, while
    // surveyed references carry the floor's bumps; the difference would scale the query's view
    // of the ceiling by up to 5 %).
    for (const Reference* r : refs) {
        input.vehicle_z += r->vehicle_in_map.z() / double(refs.size());
        input.prior_pitch_rad += r->vehicle_in_map.pitch() / double(refs.size());
        input.prior_roll_rad += r->vehicle_in_map.roll() / double(refs.size());
    }
    const cv::Matx33d K_query = query_cam.K();

    for (std::size_t k = 0; k < refs.size(); ++k) {
        const Reference& ref = *refs[k];
        ReferenceOutcome outcome;
        outcome.id = ref.id;

        t0 = Clock::now();
        ImagePyramid local;
        const ImagePyramid* ref_pyramid = ref.pyramid.get();
        if (!ref_pyramid || int(ref_pyramid->levels.size()) <= levels ||
            !ref_pyramid->preprocessedFor(preprocessing)) {
            local = ImagePyramid::build(ref.image, levels, preprocessing);
            ref_pyramid = &local;
        }
        res.times.prepare_ms += msSince(t0);

        t0 = Clock::now();
        const bool cached =
            ref.sample_points && sameSelection(ref.sample_points->options, o.sampler);
        const std::vector<cv::Point2f> points =
            cached ? ref.sample_points->points
                   : selectSamplePoints(ref.image.size(), ref.heat_map, o.sampler);
        // With a coarse pose, the plane-induced prediction: either warp the reference into the
        // query frame (compensated) or centre each search window on the predicted offset.
        std::vector<cv::Point2f> predicted;
        std::optional<cv::Matx33d> reference_to_query;
        if (hint.vehicle_pose) {
            const mrpt::poses::CPose3D query_cam_in_map = *hint.vehicle_pose + camera_on_vehicle;
            if (o.matcher.compensate_motion) {
                reference_to_query = ceilingHomography(ref_cams[k], ref.cameraInMap(), query_cam,
                                                       query_cam_in_map, h0);
            } else {
                for (const auto& p : points) {
                    cv::Point2f offset(0.f, 0.f);
                    const auto on_ceiling =
                        backProjectToCeiling(ref_cams[k], ref.cameraInMap(), cv::Point2d(p), h0);
                    if (on_ceiling) {
                        if (const auto q =
                                projectToImage(query_cam, query_cam_in_map, *on_ceiling)) {
                            offset = cv::Point2f(float(q->x - p.x), float(q->y - p.y));
                        }
                    }
                    predicted.push_back(offset);
                }
            }
        }
        res.times.select_ms += msSince(t0);

        t0 = Clock::now();
        if (o.correspondence.method != CorrespondenceMethod::Sad) {
            // Baselines (issue 6): ORB or ECC in place of SAD, from the same prediction.
            std::optional<cv::Matx33d> H = reference_to_query;
            if (!H && hint.vehicle_pose) {
                H = ceilingHomography(ref_cams[k], ref.cameraInMap(), query_cam,
                                      *hint.vehicle_pose + camera_on_vehicle, h0);
            }
            CorrespondenceResult c =
                o.correspondence.method == CorrespondenceMethod::Orb
                    ? matchOrb(ref_pyramid->levels[0], query_pyramid.levels[0], H, o.correspondence)
                    : matchEcc(ref_pyramid->levels[0], query_pyramid.levels[0], points, H,
                               o.correspondence);
            outcome.matches = std::move(c.matches);
            if (!c.ok) matcher_notes += "; reference " + std::to_string(ref.id) + ": " + c.reason;
        } else {
            const auto match = [&](const std::vector<std::size_t>& which) {
                std::vector<cv::Point2f> pts, offsets;
                for (std::size_t i : which) {
                    pts.push_back(points[i]);
                    if (!predicted.empty()) offsets.push_back(predicted[i]);
                }
                return reference_to_query
                           ? matchPointsCompensated(*ref_pyramid, query_pyramid, pts,
                                                    *reference_to_query, o.matcher)
                           : matchPoints(*ref_pyramid, query_pyramid, pts, offsets, o.matcher);
            };
            // Probe: every (n / probe_points)-th point first (points run row by row, so these
            // spread over the image); the rest only if enough of them matched.
            std::vector<std::size_t> probe, rest;
            const std::size_t n = points.size();
            const std::size_t n_probe = static_cast<std::size_t>(std::max(0, hint.probe_points));
            for (std::size_t i = 0; i < n; ++i) {
                const bool in_probe = n_probe > 0 && n_probe < n && (i * n_probe) % n < n_probe;
                (in_probe ? probe : rest).push_back(i);
            }
            outcome.matches.resize(n);
            int probe_matched = 0;
            if (!probe.empty()) {
                const auto m = match(probe);
                for (std::size_t k = 0; k < probe.size(); ++k) {
                    outcome.matches[probe[k]] = m[k];
                    probe_matched += m[k].status == MatchStatus::Matched;
                }
            }
            if (!probe.empty() && probe_matched < hint.probe_min_matched) {
                res.times.match_ms += msSince(t0);
                return fallback(RefineStatus::TooFewMatches,
                                "probe: " + std::to_string(probe_matched) + " of " +
                                    std::to_string(probe.size()) + " probe points of reference " +
                                    std::to_string(ref.id) + " matched (need " +
                                    std::to_string(hint.probe_min_matched) + ")");
            }
            const auto m = match(rest);
            for (std::size_t k = 0; k < rest.size(); ++k) outcome.matches[rest[k]] = m[k];
        }
        res.times.match_ms += msSince(t0);

        t0 = Clock::now();
        const cv::Matx33d K_ref = ref_cams[k].K();
        outcome.homography = estimateHomography(outcome.matches, o.homography, &K_ref, &K_query);
        res.times.homography_ms += msSince(t0);

        // Points whose window falls outside the query cannot be tested: not in N_th's share.
        for (const auto& m : outcome.matches) {
            res.sample_points += m.status == MatchStatus::OutOfImage ? 0 : 1;
        }
        std::vector<cv::Point2f> ref_px, query_px;
        for (const auto& m : outcome.matches) {
            if (!m.inlier) continue;
            ref_px.push_back(m.reference_px);
            query_px.push_back(m.query_px);
        }
        res.inliers += int(ref_px.size());
        if (!ref_px.empty()) {
            ReferenceView view;
            view.camera = ref_cams[k];
            view.camera_in_map = ref.cameraInMap();
            view.reference_px = rectify(ref_px, ref.camera, ref_cams[k]);
            view.query_px = rectify(query_px, query_camera, query_cam);
            input.views.push_back(std::move(view));
        }
        res.references.push_back(std::move(outcome));
    }
    res.inlier_share = res.sample_points > 0 ? double(res.inliers) / res.sample_points : 0.0;

    t0 = Clock::now();
    res.estimate = estimateQueryPose(input, o.estimator);
    res.times.estimate_ms += msSince(t0);

    const auto counts = "inliers " + std::to_string(res.inliers) + " of " +
                        std::to_string(res.sample_points) + " sample points" +
                        matchStatusSummary(res.references);
    if (!res.estimate.ok) {
        const bool few = res.inliers < o.estimator.min_inliers;
        return fallback(few ? RefineStatus::TooFewMatches : RefineStatus::EstimationFailed,
                        counts + ": " + res.estimate.reason + matcher_notes);
    }
    // Acceptance (paper Sec. III-E).
    const mrpt::poses::CPose3D& refined = res.estimate.vehicle_in_map;
    res.offset_m = std::numeric_limits<double>::max();
    if (hint.vehicle_pose) {
        res.offset_m =
            std::hypot(refined.x() - hint.vehicle_pose->x(), refined.y() - hint.vehicle_pose->y());
    } else {
        for (const Reference* r : refs) {
            res.offset_m = std::min(res.offset_m, std::hypot(refined.x() - r->vehicle_in_map.x(),
                                                             refined.y() - r->vehicle_in_map.y()));
        }
    }
    if (res.inlier_share < o.acceptance.min_inlier_share) {
        return fallback(RefineStatus::LowInlierShare,
                        counts + " (share " + std::to_string(res.inlier_share) + " < N_th " +
                            std::to_string(o.acceptance.min_inlier_share) + ")");
    }
    if (res.offset_m > o.acceptance.max_offset_m) {
        return fallback(RefineStatus::OffsetTooLarge,
                        "refined pose is " + std::to_string(res.offset_m) + " m from the " +
                            (hint.vehicle_pose ? "coarse pose" : "nearest reference") + " (d_th " +
                            std::to_string(o.acceptance.max_offset_m) + " m)");
    }
    res.status = RefineStatus::Accepted;
    res.source = PoseSource::Refined;
    res.pose = res.estimate.pose;
    res.times.total_ms = msSince(t_start);
    return res;
}

}  // namespace lookup::refine
