#pragma once
// Self-supervised training labels (paper Sec. III-B): for each training query frame, the
// nearest references (by the frame's ground-truth pose, known offline) have a dense grid of
// points matched into the query; RANSAC splits them into inliers (good sample points) and
// outliers. No manual labels. Query frames are split by time: the last `held_out_share` of each
// training rawlog is held out for validation and evaluation, never trained on.

#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "lookup/database/reference_database.h"
#include "lookup/fcn/options.h"
#include "lookup/refine/homography.h"
#include "lookup/refine/types.h"

namespace lookup::fcn {

/// One (reference, query frame) pair and its grid labels.
struct LabelledPair {
    std::size_t reference = 0;  ///< database index of the reference
    std::string query_rawlog;
    std::size_t query_record = 0;  ///< rawlog record of the query image
    double query_time_s = 0;
    double distance_m = 0;             ///< between the reference and query vehicle positions [m]
    bool held_out = false;             ///< evaluation / validation pair (never trained on)
    bool usable = false;               ///< homography found with >= min_pair_inliers inliers
    std::string reason;                ///< why not usable
    std::vector<cv::Point2f> points;   ///< grid points in the reference image [px]
    std::vector<std::uint8_t> inlier;  ///< label per point: 1 = RANSAC inlier
    std::vector<std::uint8_t> target;  ///< training target per point: 1 = inlier within
                                       ///< LabelOptions::precise_inlier_px (= inlier if 0)
    int inliers = 0;
    int targets = 0;
};

struct LabelStats {
    std::size_t query_frames = 0;              ///< ceiling frames used (after query_stride)
    std::size_t frames_without_reference = 0;  ///< no reference in range (distance, time gap)
    std::size_t pairs = 0;                     ///< pairs labelled
    std::size_t usable_pairs = 0;              ///< of which usable
    std::size_t training_pairs = 0;            ///< usable and not held out
    std::size_t held_out_pairs = 0;            ///< usable and held out
    std::size_t points = 0;                    ///< labelled points of usable pairs
    std::size_t inlier_points = 0;             ///< of which inliers
    std::size_t target_points = 0;             ///< of which positive training targets
    double seconds = 0;                        ///< wall time of label generation
    double inlierShare() const { return points ? double(inlier_points) / points : 0.0; }
};

struct LabelSet {
    std::vector<LabelledPair> pairs;  ///< every labelled pair (usable or not)
    LabelStats stats;
};

/// The two cameras of a pair, lens distortion included.
struct PairCameras {
    mrpt::img::TCamera reference, query;
};

/// One labelled pair: the matches (`inlier` set by the fit), the homography fitted to them, and
/// each match's distance to it [px] (infinite where unmatched or not mapped). Reference points
/// are raw pixels of the reference image; with rectified images (see labelPair) query points and
/// the homography are in the rectified images.
struct PairLabels {
    std::vector<refine::PointMatch> matches;
    refine::HomographyResult fit;
    std::vector<double> residual_px;
};

/// Labels one pair: dense grid (spacing grid_step_px, patch_px / 2 from the borders) ->
/// matcher -> RANSAC homography, as refine::labelGridPoints. With `reference_to_query` (the
/// ceiling-plane homography predicted from known poses) each search window is centred on the
/// predicted position instead of the same pixel, so pairs farther apart than L_SR / 2 can be
/// labelled; with options.matcher.compensate_motion the reference is warped by it first
/// (refine::matchPointsCompensated, as the localiser matches), so another camera height or
/// heading is compared patch to patch at the same scale and orientation. With `cameras` of which
/// one distorts or that differ, the reference is rectified into its ideal pinhole twin and the
/// query into the same camera, as the localiser matches them
/// (`reference_to_query` then relates labelCamera(cameras) on both sides): through a distorting
/// lens the raw pixels of a plane seen twice are no homography, and the rim of the image would
/// be labelled off the plane; a query of another size or focal length would be searched at
/// another scale. Images are CV_8UC1.
PairLabels labelPair(const cv::Mat& reference, const cv::Mat& query, const LabelOptions& options,
                     const cv::Matx33d* reference_to_query, const PairCameras* cameras = nullptr);

/// The camera the query of a pair is labelled in: the reference's ideal pinhole twin when the
/// pair is rectified (see labelPair), else the query's own.
mrpt::img::TCamera labelCamera(const PairCameras& cameras);

/// Called with (done, total) during label generation.
using ProgressFn = std::function<void(std::size_t done, std::size_t total)>;

/// Labels every training rawlog against the database. A frame's vehicle pose (it picks the
/// references and predicts the search windows) comes from `pose_files` (one TUM or MRPT pose
/// file per rawlog, e.g. a lookup-localize run's poses.tum; empty = none), else from the
/// database: the survey's poses of the traverse recorded during the rawlog. Throws
/// std::runtime_error naming the file and reason for an unreadable rawlog or pose file, a
/// rawlog whose poses are unknown or do not overlap it, or one without ceiling images (label
/// of db.ini).
LabelSet generateLabels(const database::ReferenceDatabase& db,
                        const std::vector<std::string>& rawlogs,
                        const std::vector<std::string>& pose_files, const LabelOptions& options,
                        const ProgressFn& progress = {});

}  // namespace lookup::fcn
