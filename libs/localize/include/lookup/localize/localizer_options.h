#pragma once
// Options of the on-vehicle localiser (paper Sec. III-E and the system schematic, Fig. 3).

#include <mrpt/config/CLoadableOptions.h>

#include <string>

#include "lookup/common/options_table.h"
#include "lookup/database/refresh_bridge.h"
#include "lookup/localize/camera_clock.h"
#include "lookup/localize/readout_estimator.h"
#include "lookup/refine/lens_shading.h"

namespace lookup::localize {

/// Where a position comes from before the first fix and whenever lost ([localizer] coarse).
enum class CoarseMode {
    Sequence,  ///< the forward camera's sequence matcher, and the place index beside it
    Ceiling,   ///< the ceiling place index alone: no forward camera needed
    None       ///< only a start pose given or persisted
};

enum class CameraClockApply { Auto, Always, Never };

struct LocalizerOptions : public common::TableOptions<LocalizerOptions> {
    std::string ceiling_camera_label = "CEILING_CAM";  ///< query ceiling images
    std::string forward_camera_label = "FORWARD_CAM";  ///< query forward images (coarse stage)
    std::string odometry_label = "ODOMETRY";           ///< optional wheel odometry

    int references_per_query = 3;  ///< ceiling references refined against per frame
    /// The paper's interface: references nearest in time to the coarse match's time stamp.
    /// With tracking, references nearest in space to the predicted pose instead.
    bool use_tracking = true;
    /// A fix older than this (in time without a new fix) is not used to predict [s].
    double max_tracking_gap_s = 1.0;
    /// Past max_tracking_gap_s the fallback pose stays the last fix dead-reckoned with the
    /// odometry for up to this long, while its uncertainty is below the coarse pose's (a
    /// vehicle in a place the survey never entered, a stop under a bare ceiling) [s].
    double max_dead_reckoning_s = 60.0;
    /// Where no reference matches (a changed ceiling), the vehicle's motion since the previous
    /// ceiling frame is measured on the ceiling itself (that frame as the reference); where it
    /// disagrees with the odometry's by more than ceiling_odometry_min_slip of the odometry's
    /// step (a slipping wheel), it replaces the odometry's position in the dead reckoning.
    /// Elsewhere the odometry's step is the more precise. The uncertainty stays the odometry's.
    /// Nor where they disagree by more than ceiling_odometry_max_slip of the odometry's step:
    /// a step that far off is a match on something that does not move with the ceiling (dirt
    /// or a drop on the lens matches at no motion at all), not a wheel's slip.
    bool ceiling_odometry = true;
    double ceiling_odometry_min_slip = 0.1;  ///< share of the odometry's step
    double ceiling_odometry_max_slip = 0.5;  ///< share of the odometry's step
    /// Online refresh: where a fix follows a stretch that no reference refined (a changed
    /// ceiling), the stretch's frames, posed on the odometry between the two fixes as
    /// lookup-survey --refresh poses them (the refresh_* keys), become references for the rest
    /// of the run and supersede the survey's there: the next pass over the stretch (an LHD's
    /// cycle, a vehicle reversing) matches today's ceiling. In memory only; the database folder
    /// is not written.
    bool online_refresh = true;
    double online_refresh_spacing_m = 0.25;            ///< travel between the frames kept [m]
    std::size_t online_refresh_max_references = 2000;  ///< then no more are added
    database::RefreshOptions refresh;
    /// No odometry reading for this long is a dropout: the coarse stage matches without
    /// odometry and predictions are extrapolated with a growing uncertainty [s].
    double odometry_timeout_s = 0.2;
    /// Standard deviation of the ceiling camera's stamps on the vehicle clock once [time_offsets]
    /// is applied (that offset's calibration) [s]. A fix is the pose at the image's time: by
    /// this much in time it is off by the vehicle's speed x this along its motion, which every
    /// emitted pose's covariance carries.
    double image_time_sigma_s = 0.0;
    /// Against a database whose survey camera clock is known (survey_clock_max_sigma_s), the
    /// references no longer share the vehicle's lateness: a ceiling camera without a
    /// [time_offsets] value (lookup-localize sets this to 0 where it has one) stamps late by an
    /// unknown amount, of this standard deviation against true time, which widens every
    /// emitted pose's covariance along the motion [s]. The tracker's own covariance leaves it
    /// out: its fixes and predictions share the vehicle's clock.
    double uncalibrated_image_time_sigma_s = 0.015;
    /// The ceiling camera's offset against the odometry, estimated from the drive's turns and
    /// reported (camera_clock.h); where apply_camera_time_offset says, applied to its stamps
    /// once precise and significant, its sigma then adding to image_time_sigma_s.
    CameraClockOptions camera_clock;
    /// Auto: applied on a database whose survey camera's stamps are known within
    /// survey_clock_max_sigma_s (db.ini ceiling_time_offset_sigma_s), unless [time_offsets]
    /// configures the camera's (lookup-localize: then only reported). The references carry that
    /// camera's lateness, which a query driven the same way partly cancels: on a database of
    /// an uncalibrated survey, correcting the vehicle's side alone can add error
    /// (docs/benchmarks.md, "The camera's offset against the odometry, from the fixes' heading").
    CameraClockApply apply_camera_time_offset = CameraClockApply::Auto;
    double survey_clock_max_sigma_s = 0.010;  ///< [s]
    /// The ceiling cameras' rolling-shutter readouts, estimated from the rows of the refined
    /// frames and reported (readout_estimator.h); one not configured is applied once precise and
    /// significant, the survey camera's only where its clock is known (survey_clock_max_sigma_s).
    ReadoutEstimatorOptions readout;
    /// Dirt on the ceiling camera's lens, found in the mean of the images taken while the
    /// vehicle moves and divided out of each image (lens_shading.h); the lens_* keys.
    refine::LensShadingOptions lens;
    /// Acquisition (not tracking): also try references within this distance of the coarse
    /// match, one by one, before giving up, since the SAD window covers only +-L_SR/2 [m].
    double acquisition_radius_m = 4.0;
    /// Spacing of the acquisition candidates along each survey traverse [m] (traverses are
    /// thinned apart: side by side they cover different lateral offsets).
    double acquisition_step_m = 0.5;
    /// Tracking: a frame that fails at its prediction is acquired from hypotheses every
    /// acquisition_step_m along its heading, both ways, out to this many sigmas of the
    /// prediction's position uncertainty (at least one step, at most acquisition_radius_m),
    /// before it falls back to dead reckoning: a slipping wheel moves the prediction along
    /// the motion past the SAD window while its sigma still grows. 0 = off.
    double tracking_acquisition_sigmas = 3.0;
    /// Acquisition refines against every candidate and keeps the best by inlier share; it is
    /// refused as ambiguous when a candidate more than acquisition_ambiguity_distance_m away
    /// from the best fix scores within this margin of it (aliasing: rock-bolt grids, mesh).
    double acquisition_ambiguity_margin = 0.1;
    double acquisition_ambiguity_distance_m = 1.0;  ///< [m]
    /// Each acquisition candidate is probed first: acquisition_probe_points sample points
    /// spread over it are matched, and it is dropped when fewer than
    /// acquisition_probe_min_matched of them match (nearly every candidate is a wrong place,
    /// and a full match of all points cost 1 ms each, dozens per acquisition). 0 = no probe.
    int acquisition_probe_points = 8;
    int acquisition_probe_min_matched = 2;
    /// Seeds: a coarse match that is not trusted as a coarse pose (from a sequence not yet full,
    /// a global match awaiting confirmation, a lost sequence's best guess) seeds an
    /// acquisition from this many forward frames on, one per forward frame, the traverses'
    /// guesses in turn before the first fix. The acquisition must find the ceiling (best
    /// candidate, ambiguity check, confirmation) before the frame counts as refined; the frame
    /// stays lost otherwise. 0 = no seeds: only trusted coarse matches. Not with the ECC
    /// baseline, whose inlier share cannot refuse a wrong place.
    int startup_acquisition_frames = 5;
    /// Where a position comes from before the first fix and whenever lost: "sequence" (the
    /// forward camera's sequence matcher, and the ceiling place index beside it when
    /// place_search is on and the database has one), "ceiling" (the place index alone: no
    /// forward camera needed) or "none" (only a start pose given or persisted).
    CoarseMode coarse = CoarseMode::Sequence;
    /// Global acquisition from the ceiling place index (place_index.bin in the database).
    bool place_search = true;
    /// Distinct places of the index verified by the SAD refinement per global search; the
    /// second and third are what the ambiguity test compares the best with.
    int place_candidates = 3;
    /// While tracking, every this many ceiling frames the index's best places away from the
    /// track are verified: one that explains the frame about as well as the track makes the
    /// frame ambiguous and drops the track. 0 = never.
    int place_check_every = 10;
    /// Integrity of a track: a tracked fix farther from the odometry prediction than
    /// track_disagreement_m, plus track_disagreement_per_m per metre driven since the last fix,
    /// plus three sigmas of the prediction's extrapolation, disagrees with it; so many fixes in
    /// a row (track_disagreeing_fixes) drop the track.
    double track_disagreement_m = 0.3;      ///< [m]
    double track_disagreement_per_m = 0.1;  ///< [m/m]
    int track_disagreeing_fixes = 3;
    /// A tracked fix whose heading differs from the odometry prediction's by more than this
    /// many sigmas of the two together (and at least track_heading_floor_deg) is refused: the
    /// dead reckoning that follows a fix inherits its heading, so a wrong one drives the vehicle
    /// off while its ellipse stays tight.
    double track_heading_sigmas = 3.0;
    double track_heading_floor_deg = 2.0;  ///< [deg]
    /// The place check verifies only the index's places with at least this share of its best
    /// place's feature inliers.
    double place_check_rival_share = 0.5;
    /// The coarse stage is told its match is wrong after this many ceiling frames in a row
    /// without a refined fix around it; a refined fix farther than coarse_exclusion_m from it
    /// (the paper's exclusion radius) counts half of them at once.
    int coarse_reject_after_frames = 10;
    double coarse_exclusion_m = 10.0;  ///< [m]
    /// Survey traverse whose forward images feed the coarse matcher. "" = every traverse, each
    /// matched as its own sequence (laterally offset traverses would alias each other in one),
    /// the most confident match winning per frame.
    std::string coarse_traverse;
    /// true (the paper): the coarse stage searches on every forward frame, so every frame has a
    /// coarse pose to report and to judge the 10 m exclusion by. false: while LookUP tracks
    /// (the last ceiling frame was refined) forward frames only join the coarse sequence and
    /// the search, unused then, is skipped; the first frame not refined searches globally.
    bool coarse_while_tracking = true;

    /// Replay at the recorded rate, dropping ceiling frames that the localiser cannot start
    /// within max_latency_s of their arrival (what happens on the vehicle).
    bool realtime = false;
    double max_latency_s = 0.1;  ///< [s]

    bool write_debug_images = false;  ///< flow overlays into results.rawlog
    int debug_image_every = 10;       ///< one debug image every N frames

    /// Reference images kept in memory; lookup-localize faults in their heap at start-up.
    std::size_t image_cache_capacity = 64;

    // On the vehicle (docs/run-format.md: pose stream, health messages, persisted fix).
    double health_interval_s = 1.0;  ///< health message and log line every so often; 0 = none
    /// Live and real-time runs: no ceiling frame for this long reports the camera stopped
    /// (0 = never) [s].
    double camera_timeout_s = 1.0;
    /// The last refined fix is kept in this file (--persist-fix overrides) and offered as a
    /// start-up hypothesis when the run starts; "" = none.
    std::string persist_fix_file;
    double persist_interval_s = 1.0;  ///< how often the fix file is rewritten while it changes
    /// The ceiling camera's time offset carried between runs (--camera-clock overrides): read
    /// at the start (CameraClock::carry), written at the end; both only against a database
    /// whose survey camera clock is known (surveyClockKnown), since against any other the
    /// fixes' heading carries the survey camera's lateness too. "" = none.
    std::string camera_clock_file;

    /// Adds every key of its .ini section to `t` (load, save and the unknown-key check).
    void declareKeys(common::OptionsTable& t);
    void check() const;
};

}  // namespace lookup::localize
