#pragma once
// The on-vehicle localiser (paper Fig. 3): per ceiling frame,
//   coarse (forward-camera sequence match, or the odometry-propagated previous fix)
//   -> references (nearest in time to the coarse match, the paper's interface; or nearest in
//      space to the prediction while tracking)
//   -> refinement (lookup::refine::Refiner: select, match, verify, estimate)
//   -> acceptance, or fallback to the prediction / coarse pose, or "lost".
// Observations are fed in time order as they arrive; nothing here reads files, so the same
// class runs on a rawlog replay and on live sensors.

#include <mrpt/obs/CObservation.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/poses/CPose2D.h>
#include <mrpt/poses/CPosePDFGaussian.h>
#include <Eigen/Core>

#include <deque>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lookup/coarse/coarse_source.h"
#include "lookup/common/odometry_track.h"
#include "lookup/database/reference_database.h"
#include "lookup/localize/camera_clock.h"
#include "lookup/localize/localizer_options.h"
#include "lookup/localize/readout_estimator.h"
#include "lookup/refine/lens_shading.h"
#include "lookup/refine/rectifier.h"
#include "lookup/refine/refiner.h"

namespace lookup::place {
class PlaceIndex;
}

namespace lookup::localize {

enum class FrameStatus {
    Refined,   ///< refinement accepted (N_th, d_th)
    Fallback,  ///< refinement rejected or impossible: the pose dead-reckoned from the last fix
    /// Several places explain the frame nearly as well: no pose (never one of them, tightly).
    Ambiguous,
    Lost,     ///< no pose: no fix to dead-reckon from (a coarse match alone is not one)
    Dropped,  ///< not processed: the localiser was behind real time
};
const char* toString(FrameStatus s);  ///< "refined", "fallback", "ambiguous", "lost", "dropped"

/// Milliseconds spent per stage on one frame.
struct StageTimes {
    double coarse_ms = 0;  ///< forward frames since the previous ceiling frame
    double select_ms = 0;  ///< choosing and loading references
    double refine_ms = 0;  ///< lookup::refine::Refiner (all attempts)
    double place_ms = 0;   ///< ceiling place index queries (their verification is refine_ms)
    double total_ms = 0;
};

struct FrameResult {
    double time_s = 0;
    FrameStatus status = FrameStatus::Lost;
    std::string reason;  ///< why not refined (empty when refined)
    bool has_pose = false;
    mrpt::poses::CPosePDFGaussian pose;  ///< emitted vehicle pose (x, y, yaw) with covariance
    /// The floor's height under the pose [m], where the references nearest it carry heights
    /// (3-D survey poses; refine::floorFrame); none over planar (laser-derived) references.
    std::optional<double> height_m;
    std::optional<mrpt::poses::CPose2D> coarse_pose;  ///< the coarse stage's pose, if any
    std::string pose_source;                          ///< "refined", "prediction"
    double inlier_share = 0;                          ///< of the accepted / last refinement attempt
    std::vector<std::size_t> reference_indices;       ///< database indices refined against
    int refinement_attempts = 0;
    StageTimes times;
    /// The last refinement's full result (matches, inliers, per-stage times), for debug output.
    std::shared_ptr<const refine::RefineResult> refinement;
    mrpt::poses::CPose3D camera_on_vehicle;  ///< query ceiling camera mount
};

/// Whether the database's survey camera clock is known well enough for the vehicle's own
/// camera offset to be applied against it (db.ini ceiling_time_offset_sigma_s within
/// LocalizerOptions::survey_clock_max_sigma_s).
bool surveyClockKnown(const LocalizerOptions& options, const database::DatabaseInfo& db);

/// Builds the built-in coarse stage: SeqSLAM over the forward images of the database, one
/// sequence per survey traverse (or only `traverse`, LocalizerOptions::coarse_traverse); the
/// most confident usable match wins per frame. Throws std::runtime_error when the database has
/// no usable forward images.
std::unique_ptr<coarse::CoarseSource> makeSequenceCoarseSource(
    const database::ReferenceDatabase& db, const coarse::CoarseOptions& coarse_options,
    const std::string& traverse);

/// Why an observation was refused at the edge of the localiser: it is skipped and counted,
/// never turned into a pose.
struct Rejection {
    std::string kind;    ///< short name counted in timing.json, e.g. "odometry_not_finite"
    std::string detail;  ///< one line for the warning, e.g. "odometry x = nan"
};

class Localizer {
  public:
    /// `db` must outlive the localiser. `coarse` may be null (then only tracking from a
    /// known initial pose works: see setInitialPose). `coarse_uses_images`: the source is fed
    /// forward-camera frames (SeqSLAM); otherwise it is asked at each ceiling frame's time
    /// (coarse results from a file or another localiser).
    /// The localiser adds references to `db` in memory (LocalizerOptions::online_refresh).
    Localizer(database::ReferenceDatabase& db, const LocalizerOptions& options,
              const refine::RefinerOptions& refiner_options,
              std::unique_ptr<coarse::CoarseSource> coarse, bool coarse_uses_images = true);
    ~Localizer();

    /// Feeds one observation (any kind, in time order). Returns a result for every ceiling
    /// camera frame; forward images and odometry only update the internal state.
    std::optional<FrameResult> process(const mrpt::obs::CObservation::Ptr& obs);

    /// Why `obs` cannot be used, or nothing when it can (or is not for the localiser): an
    /// odometry pose or velocity that is not finite or out of range, an image that cannot be
    /// loaded, is empty, has other channels or another size than the references, intrinsics
    /// or a camera mount that are not finite, a time stamp not after the previous one of the
    /// same sensor. process() refuses such observations; see takeRejection().
    std::optional<Rejection> check(const mrpt::obs::CObservation& obs) const;
    /// The reason process() refused its last observation (cleared by the call), if it did.
    std::optional<Rejection> takeRejection() { return std::exchange(rejection_, std::nullopt); }

    /// Tells the localiser that the vehicle jumped (a replay starting again, a vehicle moved
    /// while off): fixes, odometry and the coarse stage's query history are forgotten, so the
    /// next frames start up as the first ones did. Reference views stay cached.
    void restart();

    /// Records a ceiling frame that was skipped because processing fell behind.
    FrameResult dropped(const mrpt::obs::CObservationImage& ceiling) const;

    /// Optional known start pose (e.g. from the vehicle's last parked fix).
    void setInitialPose(double time_s, const mrpt::poses::CPose2D& vehicle_pose);

    /// A start-up hypothesis (e.g. the fix persisted before a restart): until the first fix,
    /// and for at most kHypothesisFrames ceiling frames, an acquisition around `pose` is
    /// tried first (candidates within acquisition_radius_m, ambiguity check, confirmation).
    /// Only a ceiling match makes it a fix; a wrong hypothesis costs those acquisitions.
    void offerHypothesis(const mrpt::poses::CPosePDFGaussian& pose);
    static constexpr int kHypothesisFrames = 10;

    /// The database's ceiling place index, for global acquisition and the track check (see
    /// LocalizerOptions::place_search); null = none. Must outlive the localiser.
    void setPlaceIndex(const place::PlaceIndex* index) { places_ = index; }

    const LocalizerOptions& options() const { return options_; }
    /// The ceiling camera's time offset against the odometry, as estimated and applied so far.
    const CameraClock& cameraClock() const { return camera_clock_; }
    /// Starts the camera clock from the vehicle's earlier runs (CameraClock::carry).
    void carryCameraClock(const CameraClock::Estimate& earlier) { camera_clock_.carry(earlier); }
    /// The ceiling cameras' rolling-shutter readouts, as estimated and applied so far.
    const ReadoutEstimator& readoutEstimator() const { return readout_; }
    /// The ceiling camera's lens as judged so far (LocalizerOptions::lens).
    const refine::LensShading& lens() const { return lens_; }

    /// What the online refresh did so far (LocalizerOptions::online_refresh).
    struct OnlineRefreshCounts {
        std::size_t stretches = 0;   ///< stretches bridged and added
        std::size_t refused = 0;     ///< stretches left alone (too long, no closure, full)
        std::size_t references = 0;  ///< references added
        std::size_t superseded = 0;  ///< references superseded by them
    };
    const OnlineRefreshCounts& onlineRefresh() const { return online_refresh_; }

    /// References an acquisition around `pose` refines against, one by one: those within
    /// acquisition_radius_m, nearest first, each survey traverse thinned to
    /// acquisition_step_m along itself.
    std::vector<std::size_t> acquisitionCandidates(const mrpt::poses::CPose2D& pose) const;

  private:
    struct Prediction {
        mrpt::poses::CPose2D pose;
        refine::DeadReckoning motion;  ///< what the pose rests on since the fix
        /// Where the pose rests on a place the ceiling measured instead of the fix: that
        /// place's covariance, `motion` being what it rests on since that place.
        std::optional<mrpt::math::CMatrixDouble33> anchor_cov;
    };
    /// The odometry's pose at a time, extrapolated past the last reading.
    struct OdometryPose {
        mrpt::poses::CPose2D pose;
        double extrapolated_s = 0;  ///< time since the last reading (0: interpolated)
    };
    /// A ceiling frame at its image time: its stamp moved by the camera's estimated offset
    /// against the odometry, and a refined frame's heading given to that estimate.
    FrameResult processCeilingOnClock(const mrpt::obs::CObservationImage& image);
    /// Adds the (rectified) frame to the lens's mean where the vehicle has moved on since the
    /// last one added, and divides the lens's dirt out of it.
    void cleanLens(mrpt::obs::CObservationImage& query);
    FrameResult processCeiling(const mrpt::obs::CObservationImage& query);
    /// What a frame found: the refinement to report, or why there is no place.
    struct Attempt {
        std::shared_ptr<const refine::RefineResult> result;
        std::optional<std::string> ambiguous;  ///< several places explain the frame
        std::optional<std::string> dropped;    ///< the track was dropped
        std::string note;                      ///< added to a lost frame's reason
    };
    struct CoarseFix;
    FrameResult startFrame(const mrpt::obs::CObservationImage& query);
    std::optional<CoarseFix> coarseStep(FrameResult& out);
    Attempt locate(const mrpt::obs::CObservationImage& query,
                   const std::optional<CoarseFix>& coarse_fix,
                   const std::optional<Prediction>& prediction, FrameResult& out);
    /// A frame with neither a prediction's fix nor a coarse pose: the search along the dead
    /// reckoning while it is narrower than the acquisition radius, else trySeeds().
    std::shared_ptr<const refine::RefineResult> searchWhileLost(
        const mrpt::obs::CObservationImage& query, const std::optional<Prediction>& prediction,
        FrameResult& out, std::string& note);
    std::shared_ptr<const refine::RefineResult> trySeeds(const mrpt::obs::CObservationImage& query,
                                                         FrameResult& out, std::string& note);
    void auditCoarse(const std::shared_ptr<const refine::RefineResult>& result,
                     const std::optional<CoarseFix>& coarse_fix, bool tracking);
    void checkTrack(const mrpt::obs::CObservationImage& query,
                    const std::optional<Prediction>& prediction, Attempt& a, FrameResult& out);
    void emit(const Attempt& a, const std::optional<Prediction>& prediction,
              FrameResult& out) const;
    mrpt::math::CMatrixDouble33 surveyCovariance(const std::vector<std::size_t>& references) const;
    /// The odometry's velocity at `time_s` in the map frame of a vehicle heading `yaw` (x, y
    /// [m/s], yaw rate [rad/s]).
    std::optional<Eigen::Vector3d> mapVelocityAt(double time_s, double yaw) const;
    /// What an image time uncertain by `sigma_s` adds to the pose at `time_s` [s].
    mrpt::math::CMatrixDouble33 imageTimeCovariance(double time_s, double yaw,
                                                    double sigma_s) const;
    /// The lateness the references do not share with the vehicle (survey clock unknown): what
    /// it adds to the pose at `time_s` against the last fix's references.
    mrpt::math::CMatrixDouble33 unsharedLatencyCovariance(double time_s, double yaw) const;
    /// The vehicle's velocity at reference `i` in the map frame (x, y [m/s], yaw rate [rad/s])
    /// from its neighbours of the same drive (traverse and source); nullopt for a lone one.
    std::optional<Eigen::Vector3d> referenceVelocity(std::size_t i) const;
    void finishFrame(FrameResult& out);
    std::optional<double> floorHeightUnder(const mrpt::poses::CPose2D& pose) const;
    void processForward(const mrpt::obs::CObservationImage& image);
    void processOdometry(const mrpt::obs::CObservation& odo);
    struct CoarseFix {
        mrpt::poses::CPose2D pose;            ///< pose of the matched reference (or given)
        std::vector<std::size_t> references;  ///< ceiling references for that match (none:
                                              ///< those seen from `pose`)
    };
    std::optional<CoarseFix> coarseFix() const;
    /// Coarse matches not trusted (yet), one per place, from every traverse's sequence: from a
    /// not yet full sequence (once it has startup_acquisition_frames frames), a global match
    /// awaiting its confirmation, or a lost sequence's best guess. Acquisition seeds, never
    /// reported poses.
    std::vector<CoarseFix> startupSeeds() const;
    std::optional<CoarseFix> fixFromMatch(const coarse::CoarseResult& match) const;
    /// Moves the fixes' times by a change of the applied camera time offset [s].
    void retimeFixes(double moved_s);
    /// Keeps a fix's heading (fix_headings_).
    void keepFixHeading(double time_s, double yaw_rad);
    /// The last fix where the dead reckoning starts from (odometry `at_fix` there): its place,
    /// and the odometry's heading turned by the median of the recent fixes' offsets. One fix
    /// on a changed ceiling can be a degree or two off in heading while right in place.
    mrpt::poses::CPose2D deadReckoningAnchor(const common::OdometryTrack::Pose& at_fix) const;
    /// The last fix moved by the odometry since, within max_tracking_gap_s of it (tracking).
    std::optional<Prediction> predict(double time_s) const;
    /// The same without the tracking gap, within max_dead_reckoning_s: the fallback pose.
    std::optional<Prediction> deadReckon(double time_s) const;
    /// deadReckon() where the odometry has no pose: the newest place measured since the fix,
    /// moved on at the velocity the measured places show.
    Prediction withoutOdometry(double time_s) const;
    /// The vehicle's velocity from the places measured (refined or followed on the ceiling)
    /// over the last kMeasuredPlacesSpanS; nullopt where they span too short a time or the
    /// newest is more than that before `time_s`.
    std::optional<refine::VehicleMotion> measuredVelocity(double time_s) const;
    /// Keeps a frame's place when the ceiling measured it (refined or `followed`).
    void keepMeasuredPlace(const FrameResult& out, bool followed);
    /// The fallback pose from odometry: the prediction, or past the tracking gap the dead
    /// reckoning while it is more certain than the coarse pose `out` has (if any).
    std::optional<mrpt::poses::CPosePDFGaussian> deadReckonedFallback(
        const std::optional<Prediction>& prediction, const FrameResult& out) const;
    std::optional<common::OdometryTrack::Pose> odometryAt(double time_s) const;
    /// The vehicle's velocity from the odometry just before `time_s` (rolling shutter).
    std::optional<refine::VehicleMotion> velocityAt(double time_s) const;
    std::vector<std::size_t> referencesNearTime(double time_s) const;
    /// The `count` references (0: references_per_query) whose ceiling cameras stood nearest to
    /// where a camera `camera_on_vehicle` is with the vehicle at `pose`.
    std::vector<std::size_t> referencesNear(const mrpt::poses::CPose2D& pose,
                                            const mrpt::poses::CPose3D& camera_on_vehicle,
                                            std::size_t count = 0) const;
    /// The prediction with its uncertainty: the last fix's plus the dead reckoning's since.
    mrpt::poses::CPosePDFGaussian predictedPose(const Prediction& prediction) const;
    /// Whether this run may acquire at all (a search radius, not the ECC baseline).
    bool acquisitionAllowed() const;
    /// One place an acquisition tries: a reference and the vehicle pose to refine from.
    struct Candidate {
        std::size_t reference = 0;
        mrpt::poses::CPose2D hint;
    };
    /// The acquisition candidates around a coarse pose: each reference from its own pose.
    std::vector<Candidate> candidatesAround(const mrpt::poses::CPose2D& pose) const;
    /// How far along its heading a prediction is searched: tracking_acquisition_sigmas of its
    /// position sigma [m] (uncapped).
    double alongTrackReach(const Prediction& prediction) const;
    /// Candidates along a prediction's heading (a failed tracked frame's, or the dead
    /// reckoning's), out to tracking_acquisition_sigmas of its sigma (none when off).
    std::vector<Candidate> candidatesAlongTrack(
        const Prediction& prediction, const mrpt::poses::CPose3D& camera_on_vehicle) const;
    /// Refines against each candidate, keeps the best unless ambiguous, confirms it against
    /// the fix's neighbours; else `failed` (or nothing).
    std::shared_ptr<const refine::RefineResult> acquire(
        const mrpt::obs::CObservationImage& query, const std::vector<Candidate>& candidates,
        std::shared_ptr<const refine::RefineResult> failed, FrameResult& out);
    /// Where a refinement's hint comes from: a coarse match, fix or place to confirm; one of
    /// many acquisition candidates (probed first); the track's prediction (its own N_th).
    enum class Hint { Match, Candidate, Track };
    std::shared_ptr<const refine::RefineResult> refineAgainst(
        const mrpt::obs::CObservationImage& query, const std::vector<std::size_t>& refs,
        const mrpt::poses::CPose2D& hint, FrameResult& out, Hint kind = Hint::Match);
    /// The current frame's query pyramid, built at its first refinement (startFrame forgets the
    /// last frame's): a lost frame refines against dozens of candidates.
    const std::shared_ptr<const refine::ImagePyramid>& framePyramid(
        const mrpt::obs::CObservationImage& query);
    const refine::ReferenceImage& referenceView(std::size_t index);
    /// The rows of reference `index` (db.ini ceiling_readout_ms, or the readout estimated and
    /// applied since) with the survey vehicle's velocity from its traverse's neighbouring
    /// references.
    refine::RowTiming surveyRowTiming(std::size_t index, int rows) const;
    /// referenceVelocity in the reference vehicle's own frame.
    std::optional<refine::VehicleMotion> surveyVelocity(std::size_t index) const;
    /// Keeps a refined frame's rows for the readout estimate (feedReadout).
    void estimateReadout(const FrameResult& out);
    /// Gives the kept frames the odometry now covers to the readout estimate, and applies
    /// what it changed.
    void feedReadout();
    /// The readouts as the estimate now has them, against what it had (`before`): into the
    /// refiners and the references' row timing; a newly applied one restarts the camera clock.
    void applyReadouts(const ReadoutEstimator::Modelled& before);
    struct GlobalOutcome {
        std::shared_ptr<const refine::RefineResult> result;  ///< the fix, or the ambiguous one
        bool ambiguous = false;
        std::string note;  ///< why nothing was found, for the frame's reason
    };
    GlobalOutcome acquireGlobally(const mrpt::obs::CObservationImage& query, FrameResult& out);
    std::optional<std::string> trackContradicted(const mrpt::obs::CObservationImage& query,
                                                 const refine::RefineResult& tracked,
                                                 FrameResult& out);
    GlobalOutcome separatePlaces(const mrpt::obs::CObservationImage& query, FrameResult& out);
    /// A place the SAD refinement confirmed, with the references it refined against.
    struct VerifiedPlace {
        std::shared_ptr<const refine::RefineResult> result;
        std::vector<std::size_t> references;
    };
    GlobalOutcome bestPlace(const std::vector<VerifiedPlace>& verified, FrameResult& out);
    /// Why a tracked fix's heading is refused (track_heading_sigmas), or nullopt.
    std::optional<std::string> headingDisagrees(const refine::RefineResult& tracked,
                                                const Prediction& prediction) const;
    std::optional<std::string> trackDisagreesWithOdometry(const refine::RefineResult& tracked,
                                                          const Prediction& prediction);
    const place::PlaceIndex* places_ = nullptr;
    int frames_since_check_ = 0;
    /// Places an ambiguous frame left open, as they were at `time_s`: the next frames follow
    /// each with odometry and close those whose ceiling stops matching (separatePlaces).
    struct OpenPlace {
        double time_s = 0;
        mrpt::poses::CPose2D pose;
    };
    std::vector<OpenPlace> open_places_;
    int disagreeing_fixes_ = 0;  ///< tracked fixes in a row far from the odometry prediction
    int heading_refusals_ = 0;   ///< tracked fixes in a row refused for their heading

    database::ReferenceDatabase& db_;
    LocalizerOptions options_;
    refine::Refiner refiner_;
    std::shared_ptr<const refine::ImagePyramid> frame_pyramid_;  ///< framePyramid()'s
    refine::Rectifier rectifier_;  ///< every ceiling image into the database's pinhole camera
    refine::LensShading lens_;
    double lens_travel_m_ = 0;  ///< odometry travel since the last image the lens's mean took
    std::unique_ptr<coarse::CoarseSource> coarse_;
    bool coarse_uses_images_;

    std::optional<Rejection> rejection_;
    std::map<std::string, double> last_stamp_;  ///< by sensor label: checks time order
    /// The last ceiling frame's stamp, also when refused for the readout (the frame period).
    std::optional<double> previous_ceiling_s_;

    std::optional<coarse::CoarseResult> last_coarse_;
    double coarse_ms_since_frame_ = 0;
    common::OdometryTrack odometry_;
    CameraClock camera_clock_;
    ReadoutEstimator readout_;
    struct PendingRows {
        double time_s = 0, survey_speed = 0;
        refine::RowTravel rows;
    };
    std::deque<PendingRows> pending_rows_;  ///< refined frames waiting for the odometry
    /// LocalizerOptions::uncalibrated_image_time_sigma_s where it applies, else 0 [s].
    double uncalibrated_clock_sigma_s_ = 0;
    /// The survey camera clock's sigma where it is not known well enough to correct the
    /// vehicle's against (surveyClockKnown false), else 0 [s].
    double survey_clock_sigma_s_ = 0;
    /// The references of the last fix (unsharedLatencyCovariance); cleared with the track.
    std::vector<std::size_t> fix_references_;
    double travelled_since_forward_ = 0;
    bool forward_had_odometry_ = false;  ///< the previous forward frame had live odometry

    struct Fix {
        double time_s = 0;
        mrpt::poses::CPose2D pose;
        /// As emitted, less the vehicle clock's unknown lateness (uncalibrated_clock_sigma_s_).
        mrpt::math::CMatrixDouble33 cov = mrpt::math::CMatrixDouble33::Zero();
    };
    std::optional<Fix> last_fix_;
    /// The fixes' times and headings over the last kFixHeadingsSpanS, time order: against the
    /// odometry's, the rotation the dead reckoning turns the odometry by.
    std::deque<std::pair<double, double>> fix_headings_;
    static constexpr double kFixHeadingsSpanS = 0.5;

    /// Ceiling odometry (LocalizerOptions::ceiling_odometry): the previous ceiling frame with
    /// the pose the dead reckoning gave it, and the newest place the ceiling measured since the
    /// last fix (the odometry continues from there).
    struct PreviousFrame {
        double time_s = 0;
        cv::Mat image;  ///< rectified, grey or BGR (made grey only when used)
        mrpt::img::TCamera camera;
        mrpt::poses::CPose3D camera_on_vehicle;
        mrpt::poses::CPose2D pose;
        mrpt::math::CMatrixDouble33 cov;  ///< of `pose`, as the frame reported it
    };
    struct CeilingMotion {
        double time_s = 0;
        mrpt::poses::CPose2D place;  ///< where the ceiling put the vehicle at `time_s`
        /// The measured place's covariance: the previous frame's and the step's.
        mrpt::math::CMatrixDouble33 cov;
    };
    std::optional<PreviousFrame> previous_frame_;
    std::optional<CeilingMotion> ceiling_motion_;
    /// Places the ceiling measured (refined or followed), time order, over the last
    /// kMeasuredPlacesSpanS.
    std::deque<std::pair<double, mrpt::poses::CPose2D>> measured_places_;
    static constexpr double kMeasuredPlacesSpanS = 0.5;
    refine::Refiner ceiling_refiner_;  ///< grid points: the previous frame has no heat map
    /// The ceiling's step against the odometry's: within ceiling_odometry_min_slip of it (or
    /// the ceiling's own precision) they agree; beyond ceiling_odometry_max_slip of it no wheel
    /// slipped (a match on the lens); between, the wheel slipped.
    enum class StepAgreement { NotMeasured, Agrees, Slipped, BeyondSlip };
    /// A frame no reference refined: its motion from the previous frame measured on the
    /// ceiling, kept in ceiling_motion_ where the wheel slipped (or the odometry is missing).
    StepAgreement followCeiling(const mrpt::obs::CObservationImage& query, const Attempt& a,
                                FrameResult& out);
    /// What a dead-reckoned frame's reason says of the ceiling's step.
    static std::string ceilingStepNote(StepAgreement step);
    /// The previous frame as a reference: rectified, posed, prepared for ceiling_refiner_.
    refine::ReferenceImage previousView() const;
    /// The ceiling's step from `prev` to `moved` against the odometry's; Slipped where the
    /// odometry does not cover both frames.
    StepAgreement compareSteps(const PreviousFrame& prev, const mrpt::poses::CPose2D& moved,
                               double time_s) const;
    /// The ceiling's step precision frame to frame [m]: below it, steps agree.
    static constexpr double kCeilingStepPrecision_m = 0.02;
    /// Keeps `query` as the next frame's reference for ceiling odometry.
    void keepFrame(const mrpt::obs::CObservationImage& query, const FrameResult& out);
    /// Online refresh (LocalizerOptions::online_refresh): the frames of the drive kept since
    /// the refined ones before the last stretch no reference refined, one per
    /// online_refresh_spacing_m of travel (each change between refined and not kept too).
    struct DriveFrame {
        double time_s = 0;
        cv::Mat image;  ///< rectified, grey or BGR (made grey when added)
        mrpt::img::TCamera camera;
        mrpt::poses::CPose3D camera_on_vehicle;
        bool refined = false;
        database::DriveFramePose posed;  ///< odometry and travel; the fix where refined
    };
    std::vector<DriveFrame> drive_;
    OnlineRefreshCounts online_refresh_;
    std::optional<DriveFrame> last_refined_;  ///< the newest refined frame not in drive_
    double drive_travelled_m_ = 0;
    std::optional<mrpt::poses::CPose2D> drive_odometry_;  ///< the odometry at the last frame
    /// Keeps the frame in drive_ and, once a fix has closed a stretch and the margin after it
    /// is passed (or a new stretch begins), adds the stretch's references to the database.
    void refreshOnline(const mrpt::obs::CObservationImage& query, const FrameResult& out);
    /// drive_ from its first unrefined frame to the fix after the stretch, and the margin
    /// after it: the stretch bridged and added; drive_ keeps its refined tail.
    void addStretch(std::size_t first_unrefined, std::size_t fix_after);
    /// The stretch bridged from drive_'s frames and added with its margins, or counted as
    /// refused (the odometry does not close it, or online_refresh_max_references is reached).
    void addBridged(std::size_t first_unrefined, std::size_t fix_after);
    /// The current references the frames `added` supersede (`bridged`: frame not refined).
    std::vector<std::size_t> supersededBy(
        const std::vector<std::pair<database::Reference, cv::Mat>>& added,
        const std::vector<bool>& bridged) const;
    /// drive_ without frames older than the margin before the newest refined frame.
    void trimDrive();
    std::optional<mrpt::poses::CPosePDFGaussian> hypothesis_;  ///< see offerHypothesis
    int hypothesis_frames_ = 0;                                ///< frames it was tried on
    std::shared_ptr<const refine::RefineResult> tryHypothesis(
        const mrpt::obs::CObservationImage& query, FrameResult& out);
    bool fine_tracking_ = false;  ///< the last ceiling frame was refined
    /// Coarse query index of the last start-up seed tried against the ceiling.
    std::size_t last_startup_seed_ = std::numeric_limits<std::size_t>::max();
    std::size_t seed_turn_ = 0;  ///< which traverse's seed the next start-up acquisition takes
    int unverified_coarse_frames_ = 0;  ///< frames in a row the coarse match gave no fix

    // Reference views with prepared pyramids, most recently used last (bounded).
    std::map<std::size_t, refine::ReferenceImage> views_;
    std::deque<std::size_t> view_order_;
};

}  // namespace lookup::localize
