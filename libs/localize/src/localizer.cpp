#include "lookup/localize/localizer.h"

#include <mrpt/math/wrap2pi.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/system/CTicTac.h>
#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <opencv2/imgcodecs.hpp>

#include "lookup/coarse/descriptor.h"
#include "lookup/coarse/traverse_sources.h"
#include "lookup/common/camera_params.h"
#include "lookup/common/grey.h"
#include "lookup/database/heat_maps.h"
#include "lookup/localize/place_search.h"

namespace lookup::localize {

const char* toString(FrameStatus s) {
    switch (s) {
        case FrameStatus::Refined:
            return "refined";
        case FrameStatus::Fallback:
            return "fallback";
        case FrameStatus::Ambiguous:
            return "ambiguous";
        case FrameStatus::Lost:
            return "lost";
        case FrameStatus::Dropped:
            return "dropped";
    }
    return "?";
}

namespace {

mrpt::poses::CPose2D toPose2D(const mrpt::poses::CPose3D& p) {
    return mrpt::poses::CPose2D(p.x(), p.y(), p.yaw());
}

// A search that found nothing leaves no refinement of its last candidate on the frame.
void forgetRefinement(FrameResult& out) {
    out.refinement.reset();
    out.reference_indices.clear();
    out.inlier_share = 0;
}

// Odometry and mounts beyond this are garbage (a mine spans kilometres; UTM northings 1e7 m).
constexpr double kMaxCoordinateM = 1e8;

bool isLocalizerSensor(const mrpt::obs::CObservation& obs, const LocalizerOptions& o) {
    return obs.sensorLabel == o.odometry_label || obs.sensorLabel == o.forward_camera_label ||
           obs.sensorLabel == o.ceiling_camera_label;
}

std::string number(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
}

/// "x = nan" for the first of `values` (named by `names`) that is not finite or beyond
/// `limit`, or "" when all are fine.
std::string badValue(std::initializer_list<std::pair<const char*, double>> values,
                     double limit = std::numeric_limits<double>::infinity()) {
    for (const auto& [name, v] : values) {
        if (!std::isfinite(v) || std::abs(v) > limit) return std::string(name) + " = " + number(v);
    }
    return {};
}

std::optional<Rejection> checkOdometry(const mrpt::obs::CObservation& obs) {
    const auto* odo = dynamic_cast<const mrpt::obs::CObservationOdometry*>(&obs);
    if (odo == nullptr) {
        return Rejection{
            "odometry_wrong_type",
            std::string("a ") + obs.GetRuntimeClass()->className + ", not a CObservationOdometry"};
    }
    const auto& p = odo->odometry;
    std::string bad = badValue({{"x", p.x()}, {"y", p.y()}}, kMaxCoordinateM);
    if (bad.empty()) bad = badValue({{"phi", p.phi()}});
    if (bad.empty() && odo->hasVelocities) {
        const auto& v = odo->velocityLocal;
        bad = badValue({{"vx", v.vx}, {"vy", v.vy}, {"omega", v.omega}});
    }
    if (bad.empty()) return std::nullopt;
    return Rejection{"odometry_not_finite", "odometry " + bad};
}

/// Loads an external image; "" or why it cannot be used.
std::string imageProblem(const mrpt::img::CImage& image, int& width, int& height) {
    try {
        if (!image.isExternallyStored() && image.isEmpty()) return "image is empty";
        if (image.isExternallyStored()) image.forceLoad();
        width = static_cast<int>(image.getWidth());
        height = static_cast<int>(image.getHeight());
        if (width <= 0 || height <= 0) return "image is empty";
        const cv::Mat& m = image.asCvMatRef();
        if (m.depth() != CV_8U || (m.channels() != 1 && m.channels() != 3)) {
            return "image has " + std::to_string(m.channels()) + " channels of depth " +
                   std::to_string(m.depth()) + " (8-bit grey or colour expected)";
        }
    } catch (const std::exception& e) {
        // MRPT's text is "==== MRPT exception ====\nMessage: ...\nLocation: ...": keep the message.
        std::string what = e.what();
        if (const auto m = what.find("Message:"); m != std::string::npos) what = what.substr(m + 9);
        return "cannot load the image: " + what.substr(0, what.find('\n'));
    }
    return {};
}

std::optional<Rejection> checkCeiling(const mrpt::obs::CObservationImage& img) {
    int w = 0, h = 0;
    if (auto problem = imageProblem(img.image, w, h); !problem.empty()) {
        return Rejection{"image_unusable", problem};
    }
    // Any camera is rectified into the database's (refine::Rectifier), if it describes the image.
    const auto& c = img.cameraParams;
    if (w != int(c.ncols) || h != int(c.nrows)) {
        return Rejection{"image_size", common::cameraProblem(c, w, h)};
    }
    if (auto bad = common::cameraProblem(c); !bad.empty()) {
        return Rejection{"intrinsics_invalid", "camera " + bad};
    }
    std::string bad;
    const auto& m = img.cameraPose;
    bad = badValue({{"x", m.x()}, {"y", m.y()}, {"z", m.z()}}, kMaxCoordinateM);
    if (bad.empty()) bad = badValue({{"yaw", m.yaw()}, {"pitch", m.pitch()}, {"roll", m.roll()}});
    if (!bad.empty()) return Rejection{"camera_pose_not_finite", "camera mount " + bad};
    return std::nullopt;
}

bool finite(const mrpt::poses::CPosePDFGaussian& p) {
    bool ok = std::isfinite(p.mean.x()) && std::isfinite(p.mean.y()) && std::isfinite(p.mean.phi());
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) ok = ok && std::isfinite(p.cov(r, c));
    return ok;
}

/// The refiner's options with grid sample points (a query frame as the reference has no heat map).
refine::RefinerOptions gridSampling(refine::RefinerOptions o) {
    o.sampler.mode = refine::SamplingMode::Grid;
    return o;
}

// The camera clock's estimate is applied where the survey's own camera clock is known (or the
// options force it either way). Against a survey whose clock is known only to a larger sigma,
// the references' lateness may be in the estimate: it is applied where it stands out of that.
CameraClockOptions cameraClockOptions(const LocalizerOptions& o, const database::DatabaseInfo& db) {
    CameraClockOptions c = o.camera_clock;
    const bool automatic = o.apply_camera_time_offset == CameraClockApply::Auto;
    c.apply = o.apply_camera_time_offset == CameraClockApply::Always ||
              (automatic && db.ceiling_time_offset_sigma_s);
    if (automatic && !surveyClockKnown(o, db)) {
        c.contamination_s = db.ceiling_time_offset_sigma_s.value_or(0.0);
    }
    return c;
}

// The survey camera's readout is applied only where its clock is known: an uncalibrated
// camera's lateness is left to cancel between the survey's references and the vehicle, and the
// half readout after a first-row stamp is part of what cancels.
ReadoutEstimatorOptions readoutOptions(const LocalizerOptions& o,
                                       const database::DatabaseInfo& db) {
    ReadoutEstimatorOptions r = o.readout;
    r.apply_survey = surveyClockKnown(o, db);
    return r;
}

}  // namespace

bool surveyClockKnown(const LocalizerOptions& options, const database::DatabaseInfo& db) {
    const auto& sigma = db.ceiling_time_offset_sigma_s;
    return sigma && *sigma <= options.survey_clock_max_sigma_s;
}

std::unique_ptr<coarse::CoarseSource> makeSequenceCoarseSource(
    const database::ReferenceDatabase& db, const coarse::CoarseOptions& coarse_options,
    const std::string& traverse) {
    struct Sequence {
        coarse::TraverseSequence sequence;
        double last_forward_time_s = -1;
    };
    std::map<std::string, Sequence> sequences;  // by traverse name
    for (std::size_t i : db.forwardSequence()) {
        const auto& ref = db.reference(i);
        if (!traverse.empty() && ref.traverse != traverse) continue;
        auto& seq = sequences[ref.traverse];
        // Ceiling keyframes come closer than forward frames: references sharing one forward
        // frame enter once, so the sequence's windows (contrast, exclusion, tracking) span the
        // metres the coarse options were tuned for.
        if (ref.forward_time_s == seq.last_forward_time_s) continue;
        seq.last_forward_time_s = ref.forward_time_s;
        const cv::Mat image = db.forwardImage(i);
        auto& descriptors = seq.sequence.descriptors;
        if (!descriptors) {
            descriptors = std::make_shared<coarse::ReferenceDescriptors>(coarse_options);
            descriptors->setImageSize(image.cols, image.rows);
        }
        descriptors->add(ref.forward_time_s,
                         coarse::computeDescriptor(
                             mrpt::img::CImage(image, mrpt::img::SHALLOW_COPY), coarse_options),
                         ref.vehicle_pose);
        seq.sequence.reference_index.push_back(i);
    }
    std::vector<coarse::TraverseSequence> traverses;
    for (auto& [name, seq] : sequences) traverses.push_back(std::move(seq.sequence));
    auto source = coarse::makeTraverseSource(std::move(traverses), coarse_options);
    if (!source) {
        throw std::runtime_error(db.directory() + ": no forward images" +
                                 (traverse.empty()
                                      ? std::string(" in any traverse long enough for a sequence")
                                      : " for traverse '" + traverse + "'") +
                                 ": the coarse stage needs them (or give a coarse file)");
    }
    return source;
}

Localizer::Localizer(database::ReferenceDatabase& db, const LocalizerOptions& options,
                     const refine::RefinerOptions& refiner_options,
                     std::unique_ptr<coarse::CoarseSource> coarse, bool coarse_uses_images)
    : db_(db),
      options_(options),
      refiner_(refiner_options),
      rectifier_(db.info().ceiling_camera),
      lens_(options.lens),
      coarse_(std::move(coarse)),
      coarse_uses_images_(coarse_uses_images),
      camera_clock_(cameraClockOptions(options, db.info())),
      readout_(readoutOptions(options, db.info()),
               1e-3 * refiner_options.rolling_shutter.readout_ms,
               1e-3 * db.info().ceiling_readout_ms),
      uncalibrated_clock_sigma_s_(
          surveyClockKnown(options, db.info()) ? options.uncalibrated_image_time_sigma_s : 0.0),
      survey_clock_sigma_s_(surveyClockKnown(options, db.info())
                                ? 0.0
                                : db.info().ceiling_time_offset_sigma_s.value_or(0.0)),
      ceiling_refiner_(gridSampling(refiner_options)) {
    options_.check();
}

Localizer::~Localizer() = default;

void Localizer::setInitialPose(double time_s, const mrpt::poses::CPose2D& vehicle_pose) {
    last_fix_ = Fix{time_s, vehicle_pose};
}

void Localizer::offerHypothesis(const mrpt::poses::CPosePDFGaussian& pose) {
    hypothesis_ = pose;
    hypothesis_frames_ = 0;
}

std::shared_ptr<const refine::RefineResult> Localizer::tryHypothesis(
    const mrpt::obs::CObservationImage& query, FrameResult& out) {
    auto result = acquire(query, candidatesAround(hypothesis_->mean), nullptr, out);
    if (result && result->accepted()) {
        hypothesis_.reset();
        return result;
    }
    // Not here (yet): the frame goes on as without a hypothesis.
    out.refinement.reset();
    out.reference_indices.clear();
    out.inlier_share = 0;
    if (++hypothesis_frames_ >= kHypothesisFrames) hypothesis_.reset();
    return nullptr;
}

std::optional<FrameResult> Localizer::process(const mrpt::obs::CObservation::Ptr& obs) {
    rejection_.reset();
    if (!obs) return std::nullopt;
    rejection_ = check(*obs);
    if (obs->sensorLabel == options_.ceiling_camera_label &&
        (!rejection_ || rejection_->kind == "readout_exceeds_frame_period")) {
        previous_ceiling_s_ = mrpt::Clock::toDouble(obs->timestamp);  // refused or not
    }
    if (rejection_) return std::nullopt;
    if (isLocalizerSensor(*obs, options_)) {
        last_stamp_[obs->sensorLabel] = mrpt::Clock::toDouble(obs->timestamp);
    }
    if (obs->sensorLabel == options_.odometry_label) {
        processOdometry(*obs);
        return std::nullopt;
    }
    const auto* image = dynamic_cast<const mrpt::obs::CObservationImage*>(obs.get());
    if (image == nullptr) return std::nullopt;
    if (obs->sensorLabel == options_.forward_camera_label) {
        processForward(*image);
        return std::nullopt;
    }
    if (obs->sensorLabel == options_.ceiling_camera_label) {
        return processCeilingOnClock(*image);
    }
    return std::nullopt;
}

std::optional<Rejection> Localizer::check(const mrpt::obs::CObservation& obs) const {
    if (!isLocalizerSensor(obs, options_)) return std::nullopt;
    const double t = mrpt::Clock::toDouble(obs.timestamp);
    if (obs.timestamp == INVALID_TIMESTAMP || !std::isfinite(t)) {
        return Rejection{"time_invalid", "no valid time stamp"};
    }
    if (const auto last = last_stamp_.find(obs.sensorLabel);
        last != last_stamp_.end() && t <= last->second) {
        return Rejection{"time_backwards", "time stamp " + number(t - last->second) +
                                               " s after the previous '" + obs.sensorLabel + "'"};
    }
    if (obs.sensorLabel == options_.odometry_label) return checkOdometry(obs);
    const auto* image = dynamic_cast<const mrpt::obs::CObservationImage*>(&obs);
    if (image == nullptr) {
        return Rejection{"not_an_image", std::string("a ") + obs.GetRuntimeClass()->className +
                                             ", not a CObservationImage"};
    }
    if (obs.sensorLabel == options_.ceiling_camera_label) {
        // A rolling shutter reads its rows within one frame period: a longer readout is a
        // wrong setting (milliseconds taken for microseconds, another camera's value).
        const double readout_ms = refiner_.options().rolling_shutter.readout_ms;
        if (readout_ms > 0 && previous_ceiling_s_ &&
            1e3 * (t - *previous_ceiling_s_) <= readout_ms) {
            return Rejection{"readout_exceeds_frame_period",
                             "frame " + number(1e3 * (t - *previous_ceiling_s_)) +
                                 " ms after the previous one, within [refine.rolling_shutter] "
                                 "readout_ms = " +
                                 number(readout_ms)};
        }
        return checkCeiling(*image);
    }
    if (!coarse_ || !coarse_uses_images_) return std::nullopt;  // forward images unused
    int w = 0, h = 0;
    if (auto problem = imageProblem(image->image, w, h); !problem.empty()) {
        return Rejection{"forward_image_unusable", problem};
    }
    return std::nullopt;
}

FrameResult Localizer::dropped(const mrpt::obs::CObservationImage& ceiling) const {
    FrameResult r;
    r.time_s = mrpt::Clock::toDouble(ceiling.timestamp);
    r.status = FrameStatus::Dropped;
    r.reason = "processing behind real time";
    return r;
}

void Localizer::restart() {
    last_coarse_.reset();
    coarse_ms_since_frame_ = 0;
    odometry_.clear();
    pending_rows_.clear();
    travelled_since_forward_ = 0;
    forward_had_odometry_ = false;
    last_fix_.reset();
    previous_frame_.reset();
    ceiling_motion_.reset();
    measured_places_.clear();
    fix_headings_.clear();
    drive_.clear();
    last_refined_.reset();
    drive_odometry_.reset();
    fine_tracking_ = false;
    last_startup_seed_ = std::numeric_limits<std::size_t>::max();
    seed_turn_ = 0;
    unverified_coarse_frames_ = 0;
    frames_since_check_ = 0;
    open_places_.clear();
    disagreeing_fixes_ = 0;
    heading_refusals_ = 0;
    last_stamp_.clear();
    previous_ceiling_s_.reset();
    if (coarse_) coarse_->restart();
}

void Localizer::processOdometry(const mrpt::obs::CObservation& obs) {
    const auto* odo = dynamic_cast<const mrpt::obs::CObservationOdometry*>(&obs);
    if (odo == nullptr) return;
    const double t = mrpt::Clock::toDouble(odo->timestamp);
    // check() refused a reading out of order already; never corrupt the track
    if (!odometry_.empty() && t <= odometry_.lastTime()) return;
    if (!odometry_.empty()) {
        const double step = common::signedTravel(odometry_.lastPose(), odo->odometry);
        travelled_since_forward_ += step;
        lens_travel_m_ += std::abs(step);
    }
    odometry_.add(t, odo->odometry);
    // Keep what dead reckoning can need: back to the last fix (bounded by the tracking gap, or
    // by max_dead_reckoning_s).
    double keep_from = t - 2 * options_.max_tracking_gap_s - 1.0;
    if (last_fix_) {
        keep_from = std::min(
            keep_from, std::max(last_fix_->time_s - 1.0, t - options_.max_dead_reckoning_s - 1.0));
    }
    odometry_.forgetBefore(keep_from);
}

std::optional<common::OdometryTrack::Pose> Localizer::odometryAt(double t) const {
    return odometry_.at(t, options_.max_tracking_gap_s);
}

std::optional<refine::VehicleMotion> Localizer::velocityAt(double t) const {
    // Over the odometry's velocity span up to t: the frame's stamp is the newest observation.
    if (odometry_.size() < 2) return std::nullopt;
    const double t1 = std::min(t, odometry_.lastTime()),
                 t0 = t1 - common::OdometryTrack::kVelocitySpanS;
    if (t - t1 > options_.odometry_timeout_s) return std::nullopt;
    const auto p0 = odometry_.at(t0), p1 = odometry_.at(t1);
    if (!p0 || !p1) return std::nullopt;
    const mrpt::poses::CPose2D d = p1->pose - p0->pose;  // in the vehicle's frame at t0
    return refine::VehicleMotion{d.x() / (t1 - t0), d.y() / (t1 - t0), d.phi() / (t1 - t0)};
}

std::optional<Localizer::Prediction> Localizer::predict(double t) const {
    if (!last_fix_ || t - last_fix_->time_s > options_.max_tracking_gap_s) return std::nullopt;
    return deadReckon(t);
}

std::optional<Localizer::Prediction> Localizer::deadReckon(double t) const {
    const double gap = std::max(options_.max_tracking_gap_s, options_.max_dead_reckoning_s);
    if (!last_fix_ || t - last_fix_->time_s > gap) return std::nullopt;
    const auto odo_now = odometryAt(t), odo_fix = odometryAt(last_fix_->time_s);
    if (!odo_now || !odo_fix) return withoutOdometry(t);
    const mrpt::poses::CPose2D delta = odo_now->pose - odo_fix->pose;
    // Where the ceiling measured a place since the fix, the odometry continues from there;
    // the uncertainty stays that of the odometry's distance.
    const auto odo_then = ceiling_motion_ && ceiling_motion_->time_s > last_fix_->time_s
                              ? odometryAt(ceiling_motion_->time_s)
                              : std::nullopt;
    const auto pose = odo_then ? ceiling_motion_->place + (odo_now->pose - odo_then->pose)
                               : deadReckoningAnchor(*odo_fix) + delta;
    // Both ends extrapolated lie in the same gap in the readings: the later one's error bounds
    // the motion's. An end interpolated inside a dropout is as uncertain as one extrapolated
    // from the nearer reading.
    const auto uncovered_s = [&](const common::OdometryTrack::Pose& p) {
        return p.extrapolated_s + (p.gap_s > options_.odometry_timeout_s ? p.inside_gap_s : 0.0);
    };
    const double extrapolated_s = std::max(uncovered_s(*odo_now), uncovered_s(*odo_fix));
    // A turn inside a dropout is not the straight line between its readings (the speed's
    // change is bounded by the extrapolation above; the turn's, fast at a corner, is not).
    refine::DeadReckoning motion{delta.translation().norm(), extrapolated_s, true};
    for (const auto* p : {&*odo_now, &*odo_fix}) {
        if (p->gap_s <= options_.odometry_timeout_s) continue;
        const double share = p->inside_gap_s / p->gap_s;  // at most a half
        const double turn = p->gap_turn_rad * share;
        motion.dropout_yaw_rad = std::hypot(motion.dropout_yaw_rad, turn);
        motion.dropout_xy_m =
            std::hypot(motion.dropout_xy_m, 0.5 * (1 - share) * turn * p->gap_distance_m);
    }
    return Prediction{pose, motion, std::nullopt};
}

void Localizer::keepFixHeading(double t, double yaw) {
    fix_headings_.emplace_back(t, yaw);
    while (t - fix_headings_.front().first > kFixHeadingsSpanS) fix_headings_.pop_front();
}

mrpt::poses::CPose2D Localizer::deadReckoningAnchor(
    const common::OdometryTrack::Pose& at_fix) const {
    // Each fix against the odometry as it reads now (as the dead reckoning's own motion is),
    // where the readings cover the fix's time.
    std::vector<double> offsets;
    bool with_last_fix = false;
    for (const auto& [t, yaw] : fix_headings_) {
        const auto odo = odometryAt(t);
        if (odo && odo->extrapolated_s <= options_.odometry_timeout_s &&
            odo->gap_s <= options_.odometry_timeout_s) {
            offsets.push_back(mrpt::math::wrapToPi(yaw - odo->pose.phi()));
            with_last_fix = t == last_fix_->time_s;
        }
    }
    // Three at least, the last fix's among them: a median of two is their mean.
    if (offsets.size() < 3 || !with_last_fix) return last_fix_->pose;
    const double newest = offsets.back();
    for (double& o : offsets) o = mrpt::math::wrapToPi(o - newest);  // none wraps around
    std::nth_element(offsets.begin(), offsets.begin() + offsets.size() / 2, offsets.end());
    const double offset = newest + offsets[offsets.size() / 2];
    return {last_fix_->pose.x(), last_fix_->pose.y(),
            mrpt::math::wrapToPi(at_fix.pose.phi() + offset)};
}

Localizer::Prediction Localizer::withoutOdometry(double t) const {
    double since = last_fix_->time_s;
    mrpt::poses::CPose2D pose = last_fix_->pose;
    std::optional<mrpt::math::CMatrixDouble33> anchor_cov;
    if (ceiling_motion_ && ceiling_motion_->time_s > since) {
        since = ceiling_motion_->time_s;
        pose = ceiling_motion_->place;
        anchor_cov = ceiling_motion_->cov;
    }
    const double dt = t - since;
    const auto v = measuredVelocity(t);
    // With no velocity either, the vehicle's motion since that place is unknown.
    if (!v) return Prediction{pose, {0.0, dt, false}, anchor_cov};
    const mrpt::poses::CPose2D step(v->vx_mps * dt, v->vy_mps * dt, v->yaw_rate_radps * dt);
    return Prediction{pose + step, {step.translation().norm(), dt, true}, anchor_cov};
}

std::optional<refine::VehicleMotion> Localizer::measuredVelocity(double t) const {
    // Over at least 0.2 s: one refined place's few centimetres would dominate a single step.
    if (measured_places_.size() < 2) return std::nullopt;
    const auto& [t0, p0] = measured_places_.front();
    const auto& [t1, p1] = measured_places_.back();
    if (t1 - t0 < 0.2 || t - t1 > kMeasuredPlacesSpanS) return std::nullopt;
    const mrpt::poses::CPose2D d = p1 - p0;
    return refine::VehicleMotion{d.x() / (t1 - t0), d.y() / (t1 - t0),
                                 mrpt::math::wrapToPi(d.phi()) / (t1 - t0)};
}

void Localizer::keepMeasuredPlace(const FrameResult& out, bool followed) {
    if (!out.has_pose || !last_fix_ ||
        (out.status != FrameStatus::Refined && !(followed && out.pose_source == "prediction"))) {
        if (!last_fix_) measured_places_.clear();
        return;
    }
    measured_places_.emplace_back(out.time_s, out.pose.mean);
    while (out.time_s - measured_places_.front().first > kMeasuredPlacesSpanS) {
        measured_places_.pop_front();
    }
}

void Localizer::processForward(const mrpt::obs::CObservationImage& image) {
    if (!coarse_ || !coarse_uses_images_) return;
    mrpt::system::CTicTac timer;
    coarse::CoarseQuery q;
    q.time_s = mrpt::Clock::toDouble(image.timestamp);
    q.forward_image = &image.image;
    q.search = options_.coarse_while_tracking || !fine_tracking_;
    // While the ceiling confirms the place, a wrong coarse track is contradicted by the fixes
    // (processCeiling), so the coarse stage's own audit is not needed (on mine-b it was most
    // of the coarse stage's time).
    q.audit = !fine_tracking_;
    // In an odometry dropout the coarse stage matches without odometry: a distance of zero
    // would hold it at the place where the readings stopped.
    if (!odometry_.empty() && q.time_s - odometry_.lastTime() > options_.odometry_timeout_s) {
        forward_had_odometry_ = false;
    } else if (!odometry_.empty()) {
        if (forward_had_odometry_) q.travelled_m = travelled_since_forward_;
        forward_had_odometry_ = true;
        travelled_since_forward_ = 0;
    }
    last_coarse_ = coarse_->locate(q);
    coarse_ms_since_frame_ += 1e3 * timer.Tac();
}

std::optional<Localizer::CoarseFix> Localizer::coarseFix() const {
    if (!last_coarse_) return std::nullopt;
    using coarse::CoarseStatus;
    const auto status = last_coarse_->status;
    if (status != CoarseStatus::Tracking && status != CoarseStatus::Odometry &&
        status != CoarseStatus::Global && status != CoarseStatus::External) {
        return std::nullopt;
    }
    return fixFromMatch(*last_coarse_);
}

std::vector<Localizer::CoarseFix> Localizer::startupSeeds() const {
    std::vector<CoarseFix> seeds;
    if (options_.startup_acquisition_frames <= 0 || !last_coarse_ || !coarse_) return seeds;
    // Any best guess once enough frames are seen, from every traverse's sequence: the ceiling
    // check, not the coarse confidence, decides (a traverse that is not the most confident one
    // may already hold the right place; docs/benchmarks.md, "Start-up acquisition").
    std::vector<coarse::CoarseResult> guesses{*last_coarse_};
    // Every sequence's guess only until the first fix: later, while LookUP re-acquires, they
    // would cost up to one acquisition per traverse on every forward frame for little gain.
    if (!last_fix_) {
        for (auto& other : coarse_->otherMatches()) guesses.push_back(std::move(other));
    }
    for (const auto& c : guesses) {
        const bool seed = c.hasMatch() && (c.status == coarse::CoarseStatus::NotEnoughFrames ||
                                           c.status == coarse::CoarseStatus::Unconfirmed ||
                                           c.status == coarse::CoarseStatus::Lost);
        if (!seed ||
            c.query_index + 1 < static_cast<std::size_t>(options_.startup_acquisition_frames)) {
            continue;
        }
        const auto fix = fixFromMatch(c);
        if (!fix) continue;
        // Seeds closer than the acquisition radius search the same candidates.
        const bool known = std::any_of(seeds.begin(), seeds.end(), [&](const CoarseFix& s) {
            return std::hypot(s.pose.x() - fix->pose.x(), s.pose.y() - fix->pose.y()) <
                   options_.acquisition_radius_m;
        });
        if (!known) seeds.push_back(*fix);
    }
    return seeds;
}

std::optional<Localizer::CoarseFix> Localizer::fixFromMatch(const coarse::CoarseResult& c) const {
    // The paper's interface is the matched reference time stamp: the ceiling references taken
    // nearest in time to it. A coarse source without references may give only a pose.
    std::optional<double> reference_time;
    if (c.reference_index != coarse::CoarseResult::kNone) {
        reference_time = db_.reference(c.reference_index).time_s;
    } else if (std::isfinite(c.reference_time_s)) {
        reference_time = c.reference_time_s;
    }
    if (reference_time) {
        const auto nearest = db_.nearestInTime(*reference_time, 1);
        if (nearest.empty()) return std::nullopt;
        return CoarseFix{toPose2D(db_.reference(nearest.front().index).vehicle_pose),
                         referencesNearTime(*reference_time)};
    }
    if (c.coarse_pose) return CoarseFix{toPose2D(*c.coarse_pose), {}};
    return std::nullopt;
}

std::vector<std::size_t> Localizer::referencesNearTime(double time_s) const {
    std::vector<std::size_t> out;
    for (const auto& n : db_.nearestInTime(time_s, options_.references_per_query)) {
        // Where a refresh found the ceiling changed, the references are those nearest the
        // camera (filled in by the caller), not the survey's superseded ones.
        if (!db_.reference(n.index).current()) return {};
        out.push_back(n.index);
    }
    return out;
}

std::vector<std::size_t> Localizer::referencesNear(const mrpt::poses::CPose2D& pose,
                                                   const mrpt::poses::CPose3D& camera_on_vehicle,
                                                   std::size_t count) const {
    // Nearest by camera, not by vehicle: a vehicle driving against the survey, or with its
    // camera mounted elsewhere, sees the ceiling of references whose vehicles stood metres away.
    if (count == 0) count = static_cast<std::size_t>(options_.references_per_query);
    const auto camera = mrpt::poses::CPose3D(pose) + camera_on_vehicle;
    std::vector<std::size_t> out;
    for (const auto& n : db_.nearestCameras(mrpt::math::TPoint2D(camera.x(), camera.y()), count)) {
        out.push_back(n.index);
    }
    return out;
}

std::vector<std::size_t> Localizer::acquisitionCandidates(const mrpt::poses::CPose2D& pose) const {
    // Nearest first, keeping candidates of one traverse at least acquisition_step_m apart.
    // Thinning across traverses would leave lateral gaps: on mine-a a query 0.2 m beside one
    // traverse got only candidates 0.6 m beside it (another traverse's, 0.4 m nearer the seed),
    // beyond the SAD window, and start-up took 15 forward frames longer.
    std::vector<std::size_t> out;
    for (const auto& n : db_.withinRadius(mrpt::math::TPoint2D(pose.x(), pose.y()),
                                          options_.acquisition_radius_m)) {
        const auto& ref = db_.reference(n.index);
        const auto& p = ref.vehicle_pose;
        bool far_enough = true;
        for (std::size_t j : out) {
            const auto& other = db_.reference(j);
            if (other.traverse != ref.traverse) continue;
            const auto& q = other.vehicle_pose;
            if (std::hypot(p.x() - q.x(), p.y() - q.y()) < options_.acquisition_step_m) {
                far_enough = false;
                break;
            }
        }
        if (far_enough) out.push_back(n.index);
    }
    return out;
}

refine::RowTiming Localizer::surveyRowTiming(std::size_t index, int rows) const {
    refine::RowTiming t;
    const auto& ref = db_.reference(index);
    t.rows = rows;
    if (ref.source == database::kOnlineSource) {  // this run's own camera (refreshOnline)
        const auto& shutter = refiner_.options().rolling_shutter;
        t.readout_s = 1e-3 * shutter.readout_ms;
        t.stamp_row = shutter.stampRow(rows);
    } else {
        t.readout_s = readout_.surveyReadout();
        t.stamp_row =
            db_.info().ceiling_stamp_row == common::StampRow::Middle ? 0.5 * (rows - 1) : 0.0;
    }
    if (!(t.readout_s > 0)) return t;
    if (const auto v = surveyVelocity(index)) t.velocity = *v;
    return t;
}

std::optional<refine::VehicleMotion> Localizer::surveyVelocity(std::size_t index) const {
    const auto v = referenceVelocity(index);
    if (!v) return std::nullopt;  // a lone reference: seen as a global shutter's
    const double yaw = db_.reference(index).vehicle_pose.yaw();
    const double c = std::cos(yaw), s = std::sin(yaw);
    return refine::VehicleMotion{c * v->x() + s * v->y(), -s * v->x() + c * v->y(), v->z()};
}

const refine::ReferenceImage& Localizer::referenceView(std::size_t index) {
    auto it = views_.find(index);
    if (it != views_.end()) {
        view_order_.erase(std::find(view_order_.begin(), view_order_.end(), index));
        view_order_.push_back(index);
        return it->second;
    }
    const auto& ref = db_.reference(index);
    refine::ReferenceImage view;
    view.id = static_cast<std::int64_t>(index);
    view.timestamp = mrpt::Clock::fromDouble(ref.time_s);
    view.image = db_.ceilingImage(index).clone();
    view.camera = ref.ceiling_camera;
    view.vehicle_in_map = ref.vehicle_pose;
    view.camera_on_vehicle = ref.ceiling_camera_mount;
    view.timing = surveyRowTiming(index, view.image.rows);
    // A grid run on a database with heat maps does not pay for decoding them; a reference the
    // run added has none.
    if (refiner_.options().sampler.mode != refine::SamplingMode::Grid &&
        ref.source != database::kOnlineSource) {
        view.heat_map = database::loadHeatMap(db_, index);
    }
    rectifier_.rectify(view);
    view.prepare(refiner_.options().matcher);
    view.prepareSamplePoints(refiner_.options().sampler);
    while (views_.size() >= options_.image_cache_capacity) {
        views_.erase(view_order_.front());
        view_order_.pop_front();
    }
    view_order_.push_back(index);
    return views_.emplace(index, std::move(view)).first->second;
}

std::shared_ptr<const refine::RefineResult> Localizer::refineAgainst(
    const mrpt::obs::CObservationImage& query, const std::vector<std::size_t>& refs,
    const mrpt::poses::CPose2D& hint, FrameResult& out, Hint kind) {
    mrpt::system::CTicTac timer;
    std::vector<refine::ReferenceImage> views;
    for (std::size_t i : refs) views.push_back(referenceView(i));
    out.times.select_ms += 1e3 * timer.Tac();

    timer.Tic();
    refine::CoarseHint coarse_hint;
    coarse_hint.vehicle_pose = mrpt::poses::CPose3D(hint);
    if (db_.info().ceiling_height_m > 0) coarse_hint.ceiling_height_m = db_.info().ceiling_height_m;
    if (refiner_.options().rolling_shutter.readout_ms > 0) {
        coarse_hint.vehicle_motion = velocityAt(mrpt::Clock::toDouble(query.timestamp));
    }
    coarse_hint.tracked = kind == Hint::Track;
    if (kind == Hint::Candidate) {
        coarse_hint.probe_points = options_.acquisition_probe_points;
        coarse_hint.probe_min_matched = options_.acquisition_probe_min_matched;
    }
    auto result = std::make_shared<const refine::RefineResult>(
        refiner_.refine(query, coarse_hint, views, framePyramid(query)));
    out.times.refine_ms += 1e3 * timer.Tac();
    ++out.refinement_attempts;
    out.reference_indices = refs;
    out.refinement = result;
    out.inlier_share = result->inlier_share;
    return result;
}

const std::shared_ptr<const refine::ImagePyramid>& Localizer::framePyramid(
    const mrpt::obs::CObservationImage& query) {
    if (!frame_pyramid_) frame_pyramid_ = refiner_.queryPyramid(query);
    return frame_pyramid_;
}

std::vector<Localizer::Candidate> Localizer::candidatesAround(
    const mrpt::poses::CPose2D& pose) const {
    std::vector<Candidate> out;
    for (std::size_t i : acquisitionCandidates(pose)) {
        out.push_back({i, toPose2D(db_.reference(i).vehicle_pose)});
    }
    return out;
}

double Localizer::alongTrackReach(const Prediction& prediction) const {
    const auto predicted = predictedPose(prediction);
    return options_.tracking_acquisition_sigmas *
           std::sqrt(std::max(predicted.cov(0, 0), predicted.cov(1, 1)));
}

std::vector<Localizer::Candidate> Localizer::candidatesAlongTrack(
    const Prediction& prediction, const mrpt::poses::CPose3D& camera_on_vehicle) const {
    // A slipping wheel or a late clock moves the prediction along the motion, not across it:
    // hypotheses at acquisition_step_m along the heading, both ways, nearest first, out to
    // tracking_acquisition_sigmas of the prediction's sigma.
    std::vector<Candidate> out;
    if (options_.tracking_acquisition_sigmas <= 0 || !acquisitionAllowed()) return out;
    const double reach_m = std::min(alongTrackReach(prediction), options_.acquisition_radius_m);
    const double step = options_.acquisition_step_m;
    for (int k = 1; k * step <= std::max(reach_m, step) + 1e-9; ++k) {
        for (const double along : {k * step, -k * step}) {
            const mrpt::poses::CPose2D hint = prediction.pose + mrpt::poses::CPose2D(along, 0, 0);
            const auto nearest = referencesNear(hint, camera_on_vehicle, /*count=*/1);
            if (!nearest.empty()) out.push_back({nearest.front(), hint});
        }
    }
    return out;
}

std::shared_ptr<const refine::RefineResult> Localizer::acquire(
    const mrpt::obs::CObservationImage& query, const std::vector<Candidate>& candidates,
    std::shared_ptr<const refine::RefineResult> failed, FrameResult& out) {
    // The SAD window covers only +-L_SR/2 pixels: refine against each candidate's reference
    // from its hint, keep the best by inlier share, refuse it when a distant candidate scores
    // nearly as well (aliased texture), then confirm it against the fix's neighbours.
    struct Scored {
        std::shared_ptr<const refine::RefineResult> result;
        mrpt::poses::CPose2D fix;
        std::size_t reference;
    };
    // refineAgainst records its last attempt in `out`; the frame must report the one chosen.
    const auto report = [&out](const std::shared_ptr<const refine::RefineResult>& r,
                               std::vector<std::size_t> refs) {
        out.refinement = r;
        out.inlier_share = r->inlier_share;
        out.reference_indices = std::move(refs);
        return r;
    };
    const std::vector<std::size_t> failed_refs = out.reference_indices;
    std::vector<Scored> accepted;
    for (const auto& candidate : candidates) {
        auto single =
            refineAgainst(query, {candidate.reference}, candidate.hint, out, Hint::Candidate);
        if (single->accepted()) {
            accepted.push_back({single, single->pose.mean, candidate.reference});
        }
    }
    if (accepted.empty()) return failed ? report(failed, failed_refs) : nullptr;
    const auto best = std::max_element(accepted.begin(), accepted.end(), [](auto& a, auto& b) {
        return a.result->inlier_share < b.result->inlier_share;
    });
    for (const auto& other : accepted) {
        const double d = std::hypot(other.fix.x() - best->fix.x(), other.fix.y() - best->fix.y());
        if (d > options_.acquisition_ambiguity_distance_m &&
            other.result->inlier_share >
                best->result->inlier_share - options_.acquisition_ambiguity_margin) {
            auto ambiguous = std::make_shared<refine::RefineResult>(*best->result);
            ambiguous->status = refine::RefineStatus::LowInlierShare;
            ambiguous->reason = "acquisition ambiguous: fixes " + std::to_string(d) +
                                " m apart with inlier shares " +
                                std::to_string(best->result->inlier_share) + " and " +
                                std::to_string(other.result->inlier_share);
            return report(ambiguous, {best->reference});
        }
    }
    const mrpt::poses::CPose2D fix = best->fix;
    auto confirmed = refineAgainst(query, referencesNear(fix, query.cameraPose), fix, out);
    return confirmed->accepted() ? confirmed : report(best->result, {best->reference});
}

Localizer::GlobalOutcome Localizer::acquireGlobally(const mrpt::obs::CObservationImage& query,
                                                    FrameResult& out) {
    // Each distinct place the index offers is verified as an acquisition candidate is (probe,
    // refinement, confirmation against the fix's neighbours); the best verified place is the
    // fix unless another one scores nearly as well (aliased or repeating ceiling).
    GlobalOutcome g;
    const double separation_m = options_.acquisition_ambiguity_distance_m;
    const auto found = searchPlaces(
        *places_, db_, query, static_cast<std::size_t>(options_.place_candidates), separation_m);
    out.times.place_ms += found.ms;
    std::vector<VerifiedPlace> verified;
    for (const auto& place : found.places) {
        auto single =
            refineAgainst(query, {place.reference}, place.vehicle_pose, out, Hint::Candidate);
        if (!single->accepted()) continue;
        const mrpt::poses::CPose2D fix = single->pose.mean;
        auto confirmed = refineAgainst(query, referencesNear(fix, query.cameraPose), fix, out);
        if (confirmed->accepted()) {
            verified.push_back({confirmed, out.reference_indices});
        } else {
            verified.push_back({single, {place.reference}});
        }
    }
    if (verified.empty()) {
        g.note = "; place index: " + std::to_string(found.places.size()) + " places (" +
                 std::to_string(found.features) + " features), none verified";
        return g;
    }
    return bestPlace(verified, out);
}

Localizer::GlobalOutcome Localizer::separatePlaces(const mrpt::obs::CObservationImage& query,
                                                   FrameResult& out) {
    // Each open place moves with odometry since it was seen; one whose ceiling no longer
    // matches closes. One left (or one clearly best): the fix. Several: still ambiguous.
    std::vector<VerifiedPlace> alive;
    const auto now = odometryAt(out.time_s);
    for (const auto& open : open_places_) {
        if (out.time_s - open.time_s > options_.max_tracking_gap_s) continue;
        const auto then = odometryAt(open.time_s);
        const mrpt::poses::CPose2D moved =
            now && then ? open.pose + (now->pose - then->pose) : open.pose;
        auto r = refineAgainst(query, referencesNear(moved, query.cameraPose), moved, out);
        if (r->accepted()) alive.push_back({r, out.reference_indices});
    }
    open_places_.clear();
    return bestPlace(alive, out);  // none holds: nothing, and the index searches again
}

Localizer::GlobalOutcome Localizer::bestPlace(const std::vector<VerifiedPlace>& verified,
                                              FrameResult& out) {
    // The best verified place is the fix unless another one farther than the ambiguity distance
    // scores within the margin of it: then the frame is ambiguous and every place stays open.
    GlobalOutcome g;
    if (verified.empty()) return g;
    const auto best = std::max_element(verified.begin(), verified.end(), [](auto& a, auto& b) {
        return a.result->inlier_share < b.result->inlier_share;
    });
    out.refinement = best->result;
    out.inlier_share = best->result->inlier_share;
    out.reference_indices = best->references;
    g.result = best->result;
    for (const auto& other : verified) {
        const auto& a = best->result->pose.mean;
        const auto& b = other.result->pose.mean;
        const double d = std::hypot(a.x() - b.x(), a.y() - b.y());
        if (d > options_.acquisition_ambiguity_distance_m &&
            other.result->inlier_share >
                best->result->inlier_share - options_.acquisition_ambiguity_margin) {
            g.ambiguous = true;
            g.note = std::to_string(verified.size()) + " places explain the frame: " + number(d) +
                     " m apart with inlier shares " + number(best->result->inlier_share) + " and " +
                     number(other.result->inlier_share);
            break;
        }
    }
    if (g.ambiguous) {
        for (const auto& v : verified) open_places_.push_back({out.time_s, v.result->pose.mean});
    }
    return g;
}

std::optional<std::string> Localizer::trackContradicted(const mrpt::obs::CObservationImage& query,
                                                        const refine::RefineResult& tracked,
                                                        FrameResult& out) {
    // An aliased track agrees with odometry; only another place explaining the frame as well
    // tells it apart. The index's places away from the track are verified; the frame keeps
    // the track's refinement for its report.
    const auto kept_refinement = out.refinement;
    const auto kept_refs = out.reference_indices;
    const double kept_share = out.inlier_share;
    const auto found =
        searchPlaces(*places_, db_, query, static_cast<std::size_t>(options_.place_candidates),
                     options_.acquisition_ambiguity_distance_m);
    out.times.place_ms += found.ms;
    std::optional<std::string> why;
    for (const auto& place : found.places) {
        // A place with far fewer feature inliers than the index's best is not a rival; on an
        // aliased ceiling the rivals score alike and are verified.
        if (place.inliers < options_.place_check_rival_share * found.places.front().inliers) break;
        const auto& t = tracked.pose.mean;
        const double d = std::hypot(place.vehicle_pose.x() - t.x(), place.vehicle_pose.y() - t.y());
        if (d <= options_.acquisition_ambiguity_distance_m) continue;
        auto other =
            refineAgainst(query, {place.reference}, place.vehicle_pose, out, Hint::Candidate);
        if (other->accepted() &&
            other->inlier_share > tracked.inlier_share - options_.acquisition_ambiguity_margin) {
            why = "a place " + number(d) +
                  " m from the track explains the frame as well (inlier "
                  "shares " +
                  number(other->inlier_share) + " and " + number(tracked.inlier_share) +
                  "): track dropped";
            open_places_ = {{out.time_s, tracked.pose.mean}, {out.time_s, other->pose.mean}};
            break;
        }
    }
    out.refinement = kept_refinement;
    out.reference_indices = kept_refs;
    out.inlier_share = kept_share;
    return why;
}

std::optional<std::string> Localizer::headingDisagrees(const refine::RefineResult& tracked,
                                                       const Prediction& prediction) const {
    const auto predicted = predictedPose(prediction);
    const double d = std::abs(mrpt::math::wrapToPi(tracked.pose.mean.phi() - predicted.mean.phi()));
    const double sigma = std::sqrt(tracked.pose.cov(2, 2) + predicted.cov(2, 2));
    const double allowed = std::max(mrpt::DEG2RAD(options_.track_heading_floor_deg),
                                    options_.track_heading_sigmas * sigma);
    if (d <= allowed) return std::nullopt;
    return "heading " + number(mrpt::RAD2DEG(d)) + " deg off the odometry's (allowed " +
           number(mrpt::RAD2DEG(allowed)) + " deg)";
}

std::optional<std::string> Localizer::trackDisagreesWithOdometry(
    const refine::RefineResult& tracked, const Prediction& prediction) {
    // Tracked fixes are searched around the prediction, so a few centimetres of disagreement
    // are normal; fixes that keep landing far from it follow something else than the vehicle.
    const double d = std::hypot(tracked.pose.mean.x() - prediction.pose.x(),
                                tracked.pose.mean.y() - prediction.pose.y());
    const double allowed = options_.track_disagreement_m +
                           options_.track_disagreement_per_m * prediction.motion.travelled_m +
                           3 * refiner_.acceptance().extrapolationSigmaXy(prediction.motion);
    disagreeing_fixes_ = d > allowed ? disagreeing_fixes_ + 1 : 0;
    if (disagreeing_fixes_ < options_.track_disagreeing_fixes) return std::nullopt;
    disagreeing_fixes_ = 0;
    return "fixes " + number(d) + " m from the odometry prediction " +
           std::to_string(options_.track_disagreeing_fixes) + " frames in a row: track dropped";
}

FrameResult Localizer::processCeilingOnClock(const mrpt::obs::CObservationImage& image) {
    const double stamp_s = mrpt::Clock::toDouble(image.timestamp);
    const double applied_before = camera_clock_.applied();
    camera_clock_.update(odometry_);
    retimeFixes(camera_clock_.applied() - applied_before);
    feedReadout();
    mrpt::obs::CObservationImage query = rectifier_.rectify(image);
    cleanLens(query);
    query.timestamp = mrpt::Clock::fromDouble(stamp_s + camera_clock_.applied());
    FrameResult out = processCeiling(query);
    if (out.status == FrameStatus::Refined) {
        camera_clock_.addFix(stamp_s, out.pose.mean);
        estimateReadout(out);
    }
    return out;
}

void Localizer::cleanLens(mrpt::obs::CObservationImage& query) {
    const cv::Mat image = query.image.asCvMatRef();
    if (lens_travel_m_ >= options_.lens.min_travel_m) {
        lens_.add(image, refine::driveInImage(query.cameraPose, query.cameraParams));
        lens_travel_m_ = 0;
    }
    const cv::Mat clean = lens_.correct(image);
    if (clean.data != image.data) query.image = mrpt::img::CImage(clean, mrpt::img::SHALLOW_COPY);
}

void Localizer::estimateReadout(const FrameResult& out) {
    const auto& r = out.refinement;
    if (!r || !r->accepted() || !r->estimate.row_travel || out.reference_indices.empty()) return;
    double survey_speed = 0;
    for (std::size_t i : out.reference_indices) {
        // A reference this run added was seen by this camera: no survey readout in it.
        if (db_.reference(i).source == database::kOnlineSource) return;
        const auto v = surveyVelocity(i);
        if (!v) return;
        survey_speed += v->vx_mps / double(out.reference_indices.size());
    }
    pending_rows_.push_back({out.time_s, survey_speed, *r->estimate.row_travel});
}

void Localizer::feedReadout() {
    // The vehicle's speed centred on the frame: the odometry's up to the stamp lags it by half
    // a span, which at 2 m/s^2 would pass for a readout of several ms.
    constexpr double kHalfSpan_s = 0.5 * common::OdometryTrack::kVelocitySpanS;
    while (!pending_rows_.empty() && !odometry_.empty() &&
           odometry_.lastTime() >= pending_rows_.front().time_s + kHalfSpan_s) {
        const PendingRows f = pending_rows_.front();
        pending_rows_.pop_front();
        const auto a = odometryAt(f.time_s - kHalfSpan_s), b = odometryAt(f.time_s + kHalfSpan_s);
        if (!a || !b) continue;
        const double speed = (b->pose - a->pose).x() / (2 * kHalfSpan_s);
        const auto before = readout_.modelled();
        readout_.addFrame(speed, f.survey_speed, f.rows);
        applyReadouts(before);
    }
}

void Localizer::applyReadouts(const ReadoutEstimator::Modelled& before) {
    if (readout_.queryReadout() != before.query_s) {
        refiner_.setReadout(1e3 * readout_.queryReadout());
        ceiling_refiner_.setReadout(1e3 * readout_.queryReadout());
    }
    if (readout_.surveyReadout() != before.survey_s) {
        views_.clear();  // their rows' timing changed
        view_order_.clear();
    }
    if ((readout_.queryApplied() && !before.query_applied) ||
        (readout_.surveyApplied() && !before.survey_applied)) {
        // Unmodelled, a first-row stamp's half readout read as a camera early: the fixes so
        // far measured that, not the clock.
        const double applied_before = camera_clock_.applied();
        camera_clock_.forget();
        retimeFixes(camera_clock_.applied() - applied_before);
    }
}

void Localizer::retimeFixes(double moved_s) {
    // The fixes were taken when their images were, which a newly applied offset now says: the
    // track's prediction runs the odometry from there.
    if (moved_s == 0) return;
    if (last_fix_) last_fix_->time_s += moved_s;
    for (auto& [time_s, yaw] : fix_headings_) time_s += moved_s;
}

// Per ceiling frame: coarse -> locate (track, hypothesis, the ceiling's places, around the
// coarse match, start-up seeds) -> audit of the coarse stage -> track checks -> emit.
FrameResult Localizer::processCeiling(const mrpt::obs::CObservationImage& query) {
    mrpt::system::CTicTac total;
    FrameResult out = startFrame(query);
    const auto coarse_fix = coarseStep(out);
    auto prediction = options_.use_tracking ? predict(out.time_s) : std::nullopt;
    Attempt attempt = locate(query, coarse_fix, prediction, out);
    auditCoarse(attempt.result, coarse_fix, prediction.has_value());
    checkTrack(query, prediction, attempt, out);
    const auto ceiling_step = followCeiling(query, attempt, out);
    const bool followed = ceiling_step == StepAgreement::Slipped;
    if (followed && prediction) prediction = predict(out.time_s);
    emit(attempt, prediction, out);
    if (out.pose_source == "prediction") out.reason += ceilingStepNote(ceiling_step);
    finishFrame(out);
    keepMeasuredPlace(out, followed);
    keepFrame(query, out);
    refreshOnline(query, out);
    out.times.total_ms = 1e3 * total.Tac() + out.times.coarse_ms;
    return out;
}

FrameResult Localizer::startFrame(const mrpt::obs::CObservationImage& query) {
    frame_pyramid_.reset();  // framePyramid() builds this frame's on its first refinement
    FrameResult out;
    out.time_s = mrpt::Clock::toDouble(query.timestamp);
    out.camera_on_vehicle = query.cameraPose;
    out.times.coarse_ms = coarse_ms_since_frame_;
    coarse_ms_since_frame_ = 0;
    return out;
}

std::optional<Localizer::CoarseFix> Localizer::coarseStep(FrameResult& out) {
    // The forward-camera match (paper) was updated by the forward frames; a coarse source
    // without images (a file, another localiser) is asked at the ceiling frame's time.
    if (!coarse_uses_images_ && coarse_) {
        coarse::CoarseQuery q;
        q.time_s = out.time_s;
        last_coarse_ = coarse_->locate(q);
    }
    auto coarse_fix = coarseFix();
    if (coarse_fix) out.coarse_pose = coarse_fix->pose;
    return coarse_fix;
}

Localizer::Attempt Localizer::locate(const mrpt::obs::CObservationImage& query,
                                     const std::optional<CoarseFix>& coarse_fix,
                                     const std::optional<Prediction>& prediction,
                                     FrameResult& out) {
    Attempt a;
    const auto refined = [&a] { return a.result && a.result->accepted(); };
    if (prediction) {
        a.result = refineAgainst(query, referencesNear(prediction->pose, query.cameraPose),
                                 prediction->pose, out, Hint::Track);
        if (!refined()) {
            if (auto along = candidatesAlongTrack(*prediction, query.cameraPose); !along.empty()) {
                a.result = acquire(query, along, a.result, out);
            }
        }
    }
    if (hypothesis_ && last_fix_) hypothesis_.reset();  // a fix supersedes it
    if (hypothesis_ && !prediction) a.result = tryHypothesis(query, out);
    // The ceiling's own places: those an ambiguous frame left open, else the index's.
    if (!refined() && !prediction && (places_ || !open_places_.empty())) {
        auto global = open_places_.empty() ? GlobalOutcome{} : separatePlaces(query, out);
        if (!global.result && places_) global = acquireGlobally(query, out);
        if (global.ambiguous) a.ambiguous = global.note;
        if (global.result) a.result = global.result;
        a.note = global.note;
    }
    if (a.ambiguous) return a;
    if (!refined() && coarse_fix) {
        const auto refs = coarse_fix->references.empty()
                              ? referencesNear(coarse_fix->pose, query.cameraPose)
                              : coarse_fix->references;
        a.result = refineAgainst(query, refs, coarse_fix->pose, out);
        // Acquisition searches around the coarse match only when not tracking: with a recent
        // fix a failed frame is a bad view (pipes, blur), not a lost vehicle, and searching
        // would cost tens of milliseconds for nothing.
        if (!a.result->accepted() && !prediction && options_.acquisition_radius_m > 0) {
            a.result = acquire(query, candidatesAround(*out.coarse_pose), a.result, out);
        }
    }
    if (!a.result && !coarse_fix) a.result = searchWhileLost(query, prediction, out, a.note);
    return a;
}

std::shared_ptr<const refine::RefineResult> Localizer::searchWhileLost(
    const mrpt::obs::CObservationImage& query, const std::optional<Prediction>& prediction,
    FrameResult& out, std::string& note) {
    // Past the tracking gap, while the dead reckoning still knows the place better than the
    // acquisition radius, search along it instead of around untrusted coarse matches.
    const auto dead = prediction ? std::nullopt : deadReckon(out.time_s);
    const auto along = dead && alongTrackReach(*dead) < options_.acquisition_radius_m
                           ? candidatesAlongTrack(*dead, query.cameraPose)
                           : std::vector<Candidate>{};
    if (along.empty()) return trySeeds(query, out, note);
    auto result = acquire(query, along, nullptr, out);
    if (!result) {
        note = "; no ceiling match along the dead reckoning" + note;
        forgetRefinement(out);
    }
    return result;
}

std::shared_ptr<const refine::RefineResult> Localizer::trySeeds(
    const mrpt::obs::CObservationImage& query, FrameResult& out, std::string& note) {
    // Start-up, before the coarse sequence is full, or a coarse global match not confirmed yet:
    // a verified ceiling match around that match, or nothing (it is not reported as a coarse
    // pose).
    if (!acquisitionAllowed()) return nullptr;
    // Seeds are refreshed once per forward frame (ceiling frames come twice as often): a seed
    // already tried waits for the coarse stage's next frame. One acquisition per forward
    // frame, taking the traverses' seeds in turn (most trusted first): trying all of them at
    // once made start-up frames cost 250 ms instead of 60-100.
    const auto seeds = last_coarse_ && last_coarse_->query_index != last_startup_seed_
                           ? startupSeeds()
                           : std::vector<CoarseFix>{};
    if (seeds.empty()) return nullptr;
    last_startup_seed_ = last_coarse_->query_index;
    const auto& seed = seeds[seed_turn_++ % seeds.size()];
    auto result = acquire(query, candidatesAround(seed.pose), nullptr, out);
    if (!result) {
        note = "; no ceiling match around its match from " +
               std::to_string(last_coarse_->query_index + 1) + " frames" + note;
        forgetRefinement(out);
    }
    return result;
}

void Localizer::auditCoarse(const std::shared_ptr<const refine::RefineResult>& result,
                            const std::optional<CoarseFix>& coarse_fix, bool tracking) {
    // A coarse match that no ceiling view confirms for several frames, or that a refined fix
    // puts far away, is wrong (an aliased place the coarse stage holds on to): tell the coarse
    // stage so it searches again.
    const bool refined = result && result->accepted();
    const bool contradicted =
        refined && coarse_fix &&
        std::hypot(result->pose.mean.x() - coarse_fix->pose.x(),
                   result->pose.mean.y() - coarse_fix->pose.y()) > options_.coarse_exclusion_m;
    // Refined fixes are strong evidence (they passed the acceptance filters): two in a row
    // suffice; frames that merely fail around the coarse match need more.
    if (coarse_fix && ((!tracking && !refined) || contradicted)) {
        unverified_coarse_frames_ +=
            contradicted ? std::max(1, options_.coarse_reject_after_frames / 2) : 1;
        if (unverified_coarse_frames_ >= options_.coarse_reject_after_frames && coarse_) {
            coarse_->rejectLastMatch();
            unverified_coarse_frames_ = 0;
        }
    } else {
        unverified_coarse_frames_ = 0;
    }
}

void Localizer::checkTrack(const mrpt::obs::CObservationImage& query,
                           const std::optional<Prediction>& prediction, Attempt& a,
                           FrameResult& out) {
    if (!prediction || !a.result || !a.result->accepted()) return;
    if (auto why = headingDisagrees(*a.result, *prediction)) {
        // One wrong fix is refused; fixes that keep disagreeing say the odometry turned wrong
        // (a slip), and the track is dropped so that the next fix starts afresh.
        if (++heading_refusals_ >= options_.track_disagreeing_fixes) {
            heading_refusals_ = 0;
            a.dropped = *why + ", " + std::to_string(options_.track_disagreeing_fixes) +
                        " frames in a row: track dropped";
            return;
        }
        auto refused = std::make_shared<refine::RefineResult>(*a.result);
        refused->status = refine::RefineStatus::OffsetTooLarge;
        refused->reason = *why + ": fix refused";
        a.result = std::move(refused);
        return;
    }
    heading_refusals_ = 0;
    a.dropped = trackDisagreesWithOdometry(*a.result, *prediction);
    if (a.dropped || !places_ || options_.place_check_every <= 0 ||
        ++frames_since_check_ < options_.place_check_every) {
        return;
    }
    frames_since_check_ = 0;
    a.ambiguous = trackContradicted(query, *a.result, out);
}

Localizer::StepAgreement Localizer::followCeiling(const mrpt::obs::CObservationImage& query,
                                                  const Attempt& a, FrameResult& out) {
    if (!options_.ceiling_odometry || !previous_frame_ || !last_fix_)
        return StepAgreement::NotMeasured;
    if ((a.result && a.result->accepted()) || a.ambiguous || a.dropped)
        return StepAgreement::NotMeasured;
    const auto dead = deadReckon(out.time_s);
    if (!dead || !dead->motion.velocity_known) return StepAgreement::NotMeasured;
    mrpt::system::CTicTac timer;
    const auto& prev = *previous_frame_;
    const auto view = previousView();
    refine::CoarseHint hint;
    hint.vehicle_pose = mrpt::poses::CPose3D(dead->pose);
    if (db_.info().ceiling_height_m > 0) hint.ceiling_height_m = db_.info().ceiling_height_m;
    const auto& shutter = ceiling_refiner_.options().rolling_shutter;
    if (shutter.readout_ms > 0) hint.vehicle_motion = velocityAt(out.time_s);
    // The same matcher options as refiner_'s: this frame's query pyramid serves both.
    const auto r = ceiling_refiner_.refine(query, hint, {view}, framePyramid(query));
    out.times.refine_ms += 1e3 * timer.Tac();
    ++out.refinement_attempts;
    if (!r.accepted()) return StepAgreement::NotMeasured;
    // The camera's position from the ceiling, the heading from the odometry: chained frame to
    // frame, the ceiling's small rotations drift by degrees over tens of frames, the odometry's
    // do not. Where the odometry is missing, or extrapolated over a dropout (repeating the last
    // turn rate, which drifts by degrees per frame), the ceiling's step, heading included,
    // replaces it.
    const bool extrapolated =
        !odometryAt(out.time_s) || dead->motion.extrapolated_s > options_.odometry_timeout_s;
    const mrpt::poses::CPose2D mount(query.cameraPose.x(), query.cameraPose.y(), 0);
    const auto camera = r.pose.mean + mount;
    const double heading = extrapolated ? r.pose.mean.phi() : dead->pose.phi();
    const auto moved = mrpt::poses::CPose2D(camera.x(), camera.y(), heading) +
                       mrpt::poses::CPose2D(-mount.x(), -mount.y(), 0);
    if (!extrapolated) {
        const auto agreement = compareSteps(prev, moved, out.time_s);
        if (agreement != StepAgreement::Slipped) return agreement;
    }
    // The step measured on the ceiling is as uncertain as the odometry's over that distance.
    const double step_m = (moved - prev.pose).translation().norm();
    const auto step = refiner_.acceptance().deadReckoned(moved, {step_m, 0.0, true});
    ceiling_motion_ = CeilingMotion{out.time_s, moved, prev.cov + step.cov};
    return StepAgreement::Slipped;
}

refine::ReferenceImage Localizer::previousView() const {
    const auto& prev = *previous_frame_;
    refine::ReferenceImage view;
    view.id = -1;
    view.timestamp = mrpt::Clock::fromDouble(prev.time_s);
    view.image = common::greyOf(prev.image);
    view.camera = prev.camera;
    view.camera_on_vehicle = prev.camera_on_vehicle;
    view.vehicle_in_map = mrpt::poses::CPose3D(prev.pose);
    const auto& shutter = ceiling_refiner_.options().rolling_shutter;
    if (shutter.readout_ms > 0) {
        view.timing.readout_s = 1e-3 * shutter.readout_ms;
        view.timing.rows = view.image.rows;
        view.timing.stamp_row = shutter.stampRow(view.image.rows);
        if (const auto v = velocityAt(prev.time_s)) view.timing.velocity = *v;
    }
    view.prepare(ceiling_refiner_.options().matcher);
    view.prepareSamplePoints(ceiling_refiner_.options().sampler);
    return view;
}

std::string Localizer::ceilingStepNote(StepAgreement step) {
    switch (step) {
        case StepAgreement::Slipped:
            return "; dead-reckoned on the ceiling's own motion";
        case StepAgreement::BeyondSlip:
            return "; the ceiling's step is off the odometry's by more than a wheel slips "
                   "(something on the lens?): not used";
        default:
            return "";
    }
}

Localizer::StepAgreement Localizer::compareSteps(const PreviousFrame& prev,
                                                 const mrpt::poses::CPose2D& moved,
                                                 double time_s) const {
    // Frame to frame the ceiling's relief puts its steps a few per cent off: a wheel that grips
    // does better, so the ceiling's step replaces the odometry's only where they disagree. A
    // wheel slips by a share of its step; a match on the lens says the vehicle stood still.
    const auto odo_prev = odometryAt(prev.time_s), odo_now = odometryAt(time_s);
    if (!odo_prev || !odo_now) return StepAgreement::Slipped;
    const auto odo_step = (odo_now->pose - odo_prev->pose).translation();
    const double disagreement = ((moved - prev.pose).translation() - odo_step).norm();
    const double step_m = odo_step.norm();
    const auto over = [&](double share) {
        return disagreement > std::max(kCeilingStepPrecision_m, share * step_m);
    };
    if (!over(options_.ceiling_odometry_min_slip)) return StepAgreement::Agrees;
    return over(options_.ceiling_odometry_max_slip) ? StepAgreement::BeyondSlip
                                                    : StepAgreement::Slipped;
}

void Localizer::keepFrame(const mrpt::obs::CObservationImage& query, const FrameResult& out) {
    previous_frame_.reset();
    if (!options_.ceiling_odometry || !last_fix_ || !out.has_pose) return;
    const auto dead = deadReckon(out.time_s);  // the fix itself on a refined frame
    if (!dead) return;
    try {
        const cv::Mat& m = query.image.asCvMatRef();
        if (m.depth() != CV_8U || (m.channels() != 1 && m.channels() != 3)) return;
        previous_frame_ = PreviousFrame{out.time_s,       m,          query.cameraParams,
                                        query.cameraPose, dead->pose, out.pose.cov};
    } catch (const std::exception&) {
        // process() checked the image; one that cannot be read now is no reference
    }
}

void Localizer::emit(const Attempt& a, const std::optional<Prediction>& prediction,
                     FrameResult& out) const {
    if (a.ambiguous || a.dropped) {
        out.status = a.ambiguous ? FrameStatus::Ambiguous : FrameStatus::Lost;
        out.reason = a.ambiguous ? *a.ambiguous : *a.dropped;
        return;
    }
    if (a.result && a.result->accepted()) {
        out.status = FrameStatus::Refined;
        out.pose_source = "refined";
        out.has_pose = true;
        out.pose = a.result->pose;
        out.pose.cov += surveyCovariance(out.reference_indices);
        return;
    }
    out.status = FrameStatus::Fallback;
    // Without a result the note says what was searched (seeds around an untrusted coarse match).
    out.reason =
        a.result ? a.result->reason
                 : "no refinement" +
                       (a.note.empty() ? std::string(": no references to refine against") : a.note);
    if (const auto dead_reckoned = deadReckonedFallback(prediction, out)) {
        out.has_pose = true;
        out.pose_source = "prediction";
        out.pose = *dead_reckoned;
        return;
    }
    // The coarse stage names a place, or one of the places that look like it: in tunnels that
    // alias its error is metres or tens of metres with nothing to tell which, so no sigma would
    // be honest. Unconfirmed by the ceiling, it stays in the coarse columns, not the pose.
    out.status = FrameStatus::Lost;
    if (out.coarse_pose) {
        out.reason = "coarse match not confirmed by the ceiling (" + out.reason + ")";
    } else {
        out.reason = last_coarse_ ? "coarse stage not confident: " + last_coarse_->reason
                                  : "no coarse match yet";
        out.reason += a.note;
    }
}

mrpt::poses::CPosePDFGaussian Localizer::predictedPose(const Prediction& prediction) const {
    // Dead reckoning starts from the last fix (or place measured), as uncertain as that was.
    auto pose = refiner_.acceptance().deadReckoned(prediction.pose, prediction.motion);
    pose.cov += prediction.anchor_cov ? *prediction.anchor_cov : last_fix_->cov;
    return pose;
}

bool Localizer::acquisitionAllowed() const {
    // ECC is left out: its "inliers" all sample one dense warp, so an inlier share cannot tell
    // a wrong candidate's place from the right one (demo: fixes 45 m off).
    return refiner_.options().correspondence.method != refine::CorrespondenceMethod::Ecc &&
           options_.acquisition_radius_m > 0;
}

std::optional<mrpt::poses::CPosePDFGaussian> Localizer::deadReckonedFallback(
    const std::optional<Prediction>& prediction, const FrameResult& out) const {
    if (prediction) return predictedPose(*prediction);
    if (!options_.use_tracking) return std::nullopt;
    const auto dead = deadReckon(out.time_s);
    if (!dead || !dead->motion.velocity_known) return std::nullopt;
    return predictedPose(*dead);
}

mrpt::math::CMatrixDouble33 Localizer::surveyCovariance(
    const std::vector<std::size_t>& references) const {
    // A fix is measured relative to its references: their survey uncertainty adds to it.
    mrpt::math::CMatrixDouble33 cov;
    cov.setZero();
    if (references.empty()) return cov;
    for (std::size_t i : references) cov += db_.reference(i).vehicle_cov;
    cov *= 1.0 / double(references.size());
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
            if (!std::isfinite(cov(r, c))) return mrpt::math::CMatrixDouble33::Zero();
    return cov;
}

std::optional<Eigen::Vector3d> Localizer::mapVelocityAt(double time_s, double yaw) const {
    const auto v = velocityAt(time_s);  // in the vehicle's frame
    if (!v) return std::nullopt;
    const double c = std::cos(yaw), s = std::sin(yaw);
    return Eigen::Vector3d(c * v->vx_mps - s * v->vy_mps, s * v->vx_mps + c * v->vy_mps,
                           v->yaw_rate_radps);
}

mrpt::math::CMatrixDouble33 Localizer::imageTimeCovariance(double time_s, double yaw,
                                                           double sigma_s) const {
    // The vehicle moves and turns over the image time's uncertainty.
    mrpt::math::CMatrixDouble33 cov;
    cov.setZero();
    if (!(sigma_s > 0)) return cov;
    const auto rate = mapVelocityAt(time_s, yaw);
    if (!rate) return cov;
    cov.asEigen() = sigma_s * sigma_s * *rate * rate->transpose();
    return cov;
}

std::optional<Eigen::Vector3d> Localizer::referenceVelocity(std::size_t i) const {
    const auto& ref = db_.reference(i);
    // A neighbour more than a second away is across a gap in the drive, not beside it.
    const auto neighbour = [&](std::size_t j) {
        if (j >= db_.size()) return false;
        const auto& r = db_.reference(j);
        return r.traverse == ref.traverse && r.source == ref.source &&
               std::abs(r.time_s - ref.time_s) < 1.0;
    };
    const auto& a = db_.reference(i > 0 && neighbour(i - 1) ? i - 1 : i);
    const auto& b = db_.reference(neighbour(i + 1) ? i + 1 : i);
    const double dt = b.time_s - a.time_s;
    if (!(dt > 0)) return std::nullopt;
    return Eigen::Vector3d((b.vehicle_pose.x() - a.vehicle_pose.x()) / dt,
                           (b.vehicle_pose.y() - a.vehicle_pose.y()) / dt,
                           mrpt::math::wrapToPi(b.vehicle_pose.yaw() - a.vehicle_pose.yaw()) / dt);
}

mrpt::math::CMatrixDouble33 Localizer::unsharedLatencyCovariance(double time_s, double yaw) const {
    // An unknown survey camera clock is taken as late as the vehicle's camera, which holds
    // where the vehicle drives as the references' traverse did: the two shifts cancel. At
    // another speed, or against the survey's direction, what is left is the difference of the
    // two velocities times the lateness, of the survey clock's sigma.
    mrpt::math::CMatrixDouble33 cov;
    cov.setZero();
    if (!(survey_clock_sigma_s_ > 0) || fix_references_.empty()) return cov;
    const auto vehicle = mapVelocityAt(time_s, yaw);
    if (!vehicle) return cov;
    std::size_t n = 0;
    for (std::size_t i : fix_references_) {
        if (db_.reference(i).source != "survey") continue;  // placed by a drive's own fixes
        const auto reference = referenceVelocity(i);
        if (!reference) continue;
        const Eigen::Vector3d w = *vehicle - *reference;
        cov.asEigen() += w * w.transpose();
        ++n;
    }
    if (n > 0) cov.asEigen() *= survey_clock_sigma_s_ * survey_clock_sigma_s_ / double(n);
    return cov;
}

void Localizer::finishFrame(FrameResult& out) {
    if (out.coarse_pose &&
        !std::isfinite(out.coarse_pose->x() + out.coarse_pose->y() + out.coarse_pose->phi())) {
        out.coarse_pose.reset();
    }
    if (out.has_pose) {
        const double sigma_s =
            std::hypot(options_.image_time_sigma_s, camera_clock_.appliedSigma());
        out.pose.cov += imageTimeCovariance(out.time_s, out.pose.mean.phi(), sigma_s);
    }
    if (out.has_pose && !finite(out.pose)) {
        // Last line of defence: a pose or covariance that is not finite is no pose at all.
        out.reason = "non-finite " + out.pose_source + " pose or covariance" +
                     (out.reason.empty() ? "" : " (" + out.reason + ")");
        out.status = FrameStatus::Lost;
        out.has_pose = false;
        out.pose = mrpt::poses::CPosePDFGaussian();
        out.pose_source.clear();
    }
    // An ambiguous frame or a dropped track leaves no place as the track's.
    if (out.status == FrameStatus::Ambiguous || !out.has_pose) {
        last_fix_.reset();
        fix_headings_.clear();
        fix_references_.clear();
    }
    if (out.status == FrameStatus::Refined) {
        last_fix_ = Fix{out.time_s, out.pose.mean, out.pose.cov};
        keepFixHeading(out.time_s, out.pose.mean.phi());
        fix_references_ = out.reference_indices;
    }
    fine_tracking_ = out.status == FrameStatus::Refined;
    if (fine_tracking_) open_places_.clear();
    // The vehicle's unknown lateness, or one its camera clock measured but did not apply, moves
    // its fixes and predictions alike: the track keeps its own covariance, the emitted pose
    // carries it.
    if (out.has_pose) {
        out.pose.cov += imageTimeCovariance(
            out.time_s, out.pose.mean.phi(),
            std::hypot(uncalibrated_clock_sigma_s_, camera_clock_.unappliedOffset()));
        out.pose.cov += unsharedLatencyCovariance(out.time_s, out.pose.mean.phi());
        out.height_m = floorHeightUnder(out.pose.mean);
    }
}

std::optional<double> Localizer::floorHeightUnder(const mrpt::poses::CPose2D& pose) const {
    // A few references span about a metre of floor: its grade, not one reference's bump.
    constexpr std::size_t kFloorReferences = 3;
    std::vector<mrpt::poses::CPose3D> vehicles;
    for (const auto& n : db_.nearest(mrpt::math::TPoint2D(pose.x(), pose.y()), kFloorReferences)) {
        vehicles.push_back(db_.reference(n.index).vehicle_pose);
    }
    const auto floor = refine::floorFrame(vehicles);
    if (!floor) return std::nullopt;
    return refine::floorHeightAt(*floor, pose.x(), pose.y());
}

}  // namespace lookup::localize
