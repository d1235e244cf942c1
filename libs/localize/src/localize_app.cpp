#include "lookup/localize/localize_app.h"

#include <mrpt/config/CConfigFile.h>
#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/core/exceptions.h>
#include <mrpt/hwdrivers/CGenericSensor.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/system/CTicTac.h>
#include <mrpt/system/progress.h>

#include <unistd.h>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <thread>

#include "lookup/coarse/camera_stream.h"
#include "lookup/coarse/coarse_source.h"
#include "lookup/common/camera_params.h"
#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/common/heap.h"
#include "lookup/common/options_table.h"
#include "lookup/common/rawlog_io.h"
#include "lookup/localize/fix_store.h"
#include "lookup/localize/pose_stream.h"
#include "lookup/localize/sensor_clock.h"
#include "lookup/localize/vehicle_link.h"
#include "lookup/place/place_index.h"
#include "lookup/refine/correspondence_methods.h"

namespace lookup::localize {
namespace fs = std::filesystem;

namespace {

std::atomic<bool> stop_requested{false};  // lock-free: set from signal handlers
static_assert(std::atomic<bool>::is_always_lock_free);

/// The ceiling frames of a query rawlog: how many, and the time span they cover.
struct QuerySpan {
    std::size_t ceiling_frames = 0;
    double first_s = 0, last_s = 0;
};

QuerySpan scanQuery(const std::string& rawlog, const std::string& ceiling_label) {
    common::RawlogReader reader(rawlog);
    mrpt::obs::CObservation::Ptr obs;
    QuerySpan span;
    while (reader.next(obs)) {
        if (obs->sensorLabel != ceiling_label) continue;
        const double t = mrpt::Clock::toDouble(obs->timestamp);
        if (span.ceiling_frames++ == 0) span.first_s = t;
        span.first_s = std::min(span.first_s, t);
        span.last_s = std::max(span.last_s, t);
    }
    return span;
}

/// The first image of `label`, through lookup-coarse's CameraFrameStream (it refuses a rawlog
/// without such images, listing the labels present, and an image that cannot be loaded).
coarse::CameraFrame firstImage(const std::string& rawlog, const std::string& label,
                               const std::string& why_needed) {
    coarse::CameraFrameStream stream(rawlog, label, "");
    coarse::CameraFrame frame;
    try {
        stream.next(frame);
    } catch (const common::RawlogError& e) {
        const std::string what = e.what(), images = common::imagesDirectoryFor(rawlog);
        const bool no_images =
            !fs::is_directory(images) && what.find("cannot load the image") != std::string::npos;
        const bool no_label = what.find("labelled '" + label + "'") != std::string::npos;
        throw common::RawlogError(
            what +
            (no_images ? " (its images folder " + images + " does not exist)" : std::string()) +
            (no_label ? ": " + why_needed : std::string()));
    }
    return frame;
}

void checkSize(const std::string& rawlog, const coarse::CameraFrame& frame, const char* what,
               int ref_width, int ref_height, const std::string& reference) {
    const int w = int(frame.observation->image.getWidth());
    const int h = int(frame.observation->image.getHeight());
    frame.observation->image.unload();
    if (ref_width <= 0 || (w == ref_width && h == ref_height)) return;
    throw common::RawlogError(rawlog, frame.record,
                              std::string(what) + " images are " + std::to_string(w) + "x" +
                                  std::to_string(h) + ", expected " + std::to_string(ref_width) +
                                  "x" + std::to_string(ref_height) + " (" + reference + ")");
}

/// A coarse file must cover the query: none of it is an error, a part a warning.
void checkCoverage(const coarse::CoarseSource& coarse, const std::string& file,
                   const QuerySpan& query) {
    const auto span = coarse.queryTimeSpan();
    if (!span) return;
    const double overlap =
        std::min(span->second, query.last_s) - std::max(span->first, query.first_s);
    const double length = query.last_s - query.first_s;
    const auto range = [](double a, double b) {
        return "t = " + std::to_string(a) + " .. " + std::to_string(b) + " s";
    };
    const std::string where = file + " covers " + range(span->first, span->second) +
                              ", the query's ceiling frames " + range(query.first_s, query.last_s);
    if (overlap < 0 || (overlap == 0 && length > 0)) {
        throw std::runtime_error(where + ": no overlap (a file of another drive?)");
    }
    if (length > 0 && overlap < 0.9 * length) {
        std::cerr << "lookup-localize: warning: " << where << ": only "
                  << int(100 * overlap / length) << " % of the query; frames outside are lost\n";
    }
}

/// --repeat: moves each pass after the previous one, in time (one second after its end) and in
/// odometry (it continues from the previous pass's last pose, as on one long drive), so that
/// every sensor agrees that time and travel go on.
class PassShift {
  public:
    void nextPass() {
        shift_s_ = last_s_ - first_s_ + 1.0;
        origin_ = last_odometry_;
        first_raw_.reset();
    }
    /// Shifts `obs`; returns its new time stamp.
    double apply(mrpt::obs::CObservation& obs) {
        if (shift_s_ > 0) {
            obs.timestamp =
                mrpt::Clock::fromDouble(mrpt::Clock::toDouble(obs.timestamp) + shift_s_);
        }
        if (auto* odo = dynamic_cast<mrpt::obs::CObservationOdometry*>(&obs)) {
            if (origin_) {
                if (!first_raw_) first_raw_ = odo->odometry;
                odo->odometry = *origin_ + (odo->odometry - *first_raw_);
            }
            last_odometry_ = odo->odometry;
        }
        const double t = mrpt::Clock::toDouble(obs.timestamp);
        if (first_s_ < 0) first_s_ = t;
        last_s_ = std::max(last_s_, t);
        return t;
    }
    double firstStamp() const { return first_s_; }

  private:
    double shift_s_ = 0, first_s_ = -1, last_s_ = -1;
    std::optional<mrpt::poses::CPose2D> origin_, first_raw_, last_odometry_;
};

/// Refuses at the start a run that cannot work: no ceiling images, images that cannot be
/// loaded (e.g. no `<name>_Images` folder), ceiling images of another size than their
/// intrinsics say, no
/// forward images under the label the coarse stage reads, a coarse file that does not cover
/// the query. Returns the ceiling frames' span.
QuerySpan checkQuery(const LocalizeRequest& req, const LocalizerOptions& o,
                     const database::ReferenceDatabase& db, const coarse::CoarseSource* coarse,
                     bool coarse_from_images) {
    // Any ceiling camera is rectified into the database's; its images must be of its own size.
    const auto ceiling = firstImage(req.rawlog, o.ceiling_camera_label, "nothing to localise");
    const auto& camera = ceiling.observation->cameraParams;
    checkSize(req.rawlog, ceiling, "ceiling", int(camera.ncols), int(camera.nrows),
              "their intrinsics' size");
    if (coarse_from_images && !db.forwardSequence().empty()) {
        const cv::Mat reference = db.forwardImage(db.forwardSequence().front());
        checkSize(req.rawlog,
                  firstImage(req.rawlog, o.forward_camera_label,
                             "the coarse stage needs forward images (set [localizer] "
                             "forward_camera_label, or give --coarse-poses or --coarse-matches)"),
                  "forward", reference.cols, reference.rows, req.db_dir + " forward images");
    }
    const QuerySpan span = scanQuery(req.rawlog, o.ceiling_camera_label);
    if (coarse) {
        checkCoverage(*coarse, req.coarse_poses.empty() ? req.coarse_matches : req.coarse_poses,
                      span);
    }
    return span;
}

/// The database's place index when the options use one. Missing or unusable: an error with
/// coarse = ceiling (nothing else can give a first fix), else a warning and the forward
/// camera alone.
std::unique_ptr<place::PlaceIndex> loadPlaceIndex(const database::ReferenceDatabase& db,
                                                  const LocalizerOptions& o,
                                                  const place::PlaceIndexOptions& query,
                                                  bool coarse_from_files) {
    if (o.coarse == CoarseMode::None || !o.place_search) return nullptr;
    const std::string path = db.directory() + "/" + place::kPlaceIndexFile;
    const std::string fallback = ": start-up and recovery from the forward camera only";
    if (!fs::exists(path)) {
        const std::string why =
            path + ": no place index (build it: lookup-place --db " + db.directory() + ")";
        if (o.coarse == CoarseMode::Ceiling) {
            throw std::runtime_error(why + ", which coarse = ceiling needs");
        }
        // With coarse results from a file the start-up comes from them: nothing to warn of.
        if (!coarse_from_files)
            std::cerr << "lookup-localize: warning: " << why << fallback << "\n";
        return nullptr;
    }
    try {
        return std::make_unique<place::PlaceIndex>(place::PlaceIndex::load(path, db, query));
    } catch (const place::PlaceIndexError& e) {
        if (o.coarse == CoarseMode::Ceiling) throw;
        std::cerr << "lookup-localize: warning: " << e.what() << fallback << "\n";
        return nullptr;
    }
}

}  // namespace

namespace {

/// Everything one run needs: options, database, localiser and output, fed one observation at a
/// time by the replay loop or the live sensors.
class Session {
  public:
    explicit Session(const LocalizeRequest& req, const std::string& source_name)
        : req_(req), source_(source_name) {
        RunWriter::cleanLeftovers(req.out_dir);
        // Options: defaults, then the ini file, then command-line overrides.
        if (!req.ini_file.empty()) {
            const auto file = common::loadIniFile(req.ini_file);  // binary or garbled: refused
            const auto& ini = *file;
            std::vector<std::string> known = refine::RefinerOptions::sectionNames("refine");
            // [run] is what a run.ini records of the run itself (method, database, source):
            // the command line says those, so a run's run.ini can be given back as --ini.
            known.insert(known.end(),
                         {"localizer", "coarse", "place_index", "time_offsets", "run"});
            common::rejectUnknownSections(ini, known);
            common::loadAndCheck(options_, ini, "localizer");
            common::loadAndCheck(refiner_options_, ini, "refine");
            common::loadAndCheck(coarse_options_, ini, "coarse");
            common::loadAndCheck(place_options_, ini, "place_index");
            clock_ = SensorClock::fromConfig(ini, req.ini_file);
        }
        // A configured ceiling camera offset is the vehicle's calibration: the estimate then
        // checks it and is applied only when asked to, and its stamps carry no unknown lateness.
        if (clock_.configures(options_.ceiling_camera_label)) {
            if (options_.apply_camera_time_offset == CameraClockApply::Auto) {
                options_.apply_camera_time_offset = CameraClockApply::Never;
            }
            options_.uncalibrated_image_time_sigma_s = 0;
        }
        if (req.realtime >= 0) options_.realtime = req.realtime == 1;
        if (!req.sampling.empty() && req.sampling != "grid" && req.sampling != "heatmap" &&
            req.sampling != "auto") {
            throw common::ConfigError("--sampling '" + req.sampling +
                                      "': not one of grid, heatmap, auto");
        }
        if (req.sampling == "grid") refiner_options_.sampler.mode = refine::SamplingMode::Grid;
        if (req.sampling == "heatmap") {
            refiner_options_.sampler.mode = refine::SamplingMode::HeatMap;
        }
        if (!req.matcher.empty() && !refine::parseCorrespondenceMethod(
                                        req.matcher, refiner_options_.correspondence.method)) {
            throw common::ConfigError("--matcher '" + req.matcher + "': not one of sad, orb, ecc");
        }
        options_.check();
        refiner_options_.check();
        // The stream first: a bad address fails before the database is loaded.
        link_ = std::make_unique<VehicleLink>(
            options_, req.publish,
            req.persist_fix.empty() ? options_.persist_fix_file : req.persist_fix,
            options_.realtime);

        db_ = std::make_unique<database::ReferenceDatabase>(
            database::ReferenceDatabase::load(req.db_dir, options_.image_cache_capacity));
        if (req.sampling == "heatmap" && db_->info().heatmaps_dir.empty()) {
            throw std::runtime_error(req.db_dir + "/db.ini: no heat maps (run lookup-train)");
        }
        std::unique_ptr<coarse::CoarseSource> coarse;
        if (!req.coarse_matches.empty()) {
            coarse = std::make_unique<coarse::MatchFileSource>(req.coarse_matches, 1.0);
        } else if (!req.coarse_poses.empty()) {
            coarse = std::make_unique<coarse::PoseFileSource>(req.coarse_poses, 1.0);
        } else if (options_.coarse == CoarseMode::Sequence) {
            coarse = makeSequenceCoarseSource(*db_, coarse_options_, options_.coarse_traverse);
        }
        const bool coarse_from_files = !req.coarse_matches.empty() || !req.coarse_poses.empty();
        places_ = loadPlaceIndex(*db_, options_, place_options_, coarse_from_files);
        if (!req.rawlog.empty() && source_name == req.rawlog) {
            span_ = checkQuery(req, options_, *db_, coarse.get(), coarse && !coarse_from_files);
        }
        localizer_ = std::make_unique<Localizer>(*db_, options_, refiner_options_,
                                                 std::move(coarse), !coarse_from_files);
        localizer_->setPlaceIndex(places_.get());
        startCameraClock(req.camera_clock.empty() ? options_.camera_clock_file : req.camera_clock);
        link_->start(*localizer_, *db_, req.publish_wait_s);

        mrpt::config::CConfigFileMemory used;
        used.write("run", "method",
                   req.method.empty()
                       ? defaultMethodName(refiner_options_, !db_->info().heatmaps_dir.empty())
                       : req.method);
        used.write("run", "db", req.db_dir);
        used.write("run", "source", source_name);
        options_.saveToConfigFile(used, "localizer");
        refiner_options_.saveToConfigFile(used, "refine");
        coarse_options_.saveToConfigFile(used, "coarse");
        place_options_.saveToConfigFile(used, "place_index");
        clock_.saveTo(used);
        std::string used_text;
        used.getContent(used_text);
        writer_ = std::make_unique<RunWriter>(req.out_dir, used_text, options_.write_debug_images,
                                              options_.debug_image_every);
        common::prefaultHeap(referenceCacheBytes());
        // The replay clock starts now: start-up must not make the first frames late (realtime
        // drops them) nor count in frames_per_s.
        timing_.startup_s = wall_.Tac();
        wall_.Tic();
    }

    /// A run that ends by an exception says where its frames are: the run folder is untouched.
    ~Session() {
        if (!writer_ || finished_ || std::uncaught_exceptions() == 0) return;
        const std::string partial = writer_->stagingDirectory();
        if (writer_->framesWritten() == 0) {
            std::error_code ec;
            writer_.reset();
            fs::remove_all(partial, ec);
            return;
        }
        std::cerr << "lookup-localize: the run did not finish: its " << writer_->framesWritten()
                  << " frames are in " << partial << "; " << writer_->directory()
                  << " is as it was\n";
    }

    const LocalizerOptions& options() const { return options_; }
    const RunTiming& timing() const { return timing_; }
    std::size_t expectedFrames() const { return span_.ceiling_frames; }
    double elapsed() const { return wall_.Tac(); }

    /// Processes one observation. `late_s`: how long after its arrival it is being handled
    /// (real time only). Returns true for a ceiling frame (processed or dropped).
    /// `record`: its rawlog record index, named in warnings (npos: live).
    bool feed(const mrpt::obs::CObservation::Ptr& obs, double late_s = 0,
              std::size_t record = std::string::npos) {
        link_->observation(*obs, wall_.Tac());
        const double arrival_unix_s = PoseStream::unixTime() - late_s;
        const bool handled = feedLocalizer(obs, late_s, arrival_unix_s, record);
        tick();
        return handled;
    }

    /// feed() through the sensor clock ([time_offsets]): stamps corrected, observations fed in
    /// the corrected order. `arrival_s`: elapsed() when it arrived (real time: lateness is
    /// counted from then, the hold included). Returns how many ceiling frames were handled.
    std::size_t feedClocked(const mrpt::obs::CObservation::Ptr& obs, double late_s,
                            double arrival_s, std::size_t record = std::string::npos) {
        if (clock_.empty()) return feed(obs, late_s, record) ? 1 : 0;
        return feedItems(clock_.push({obs, arrival_s, record}));
    }
    /// What the sensor clock still holds (end of a pass, end of the run).
    std::size_t flushClock() { return feedItems(clock_.flush()); }

    /// Health checks and messages; also called while no observation arrives.
    void tick() { link_->tick(wall_.Tac()); }

    /// Sleeps until `elapsed() >= until_s`, ticking the health checks meanwhile.
    void sleepUntil(double until_s) {
        for (double now = elapsed(); now < until_s && !stop_requested; now = elapsed()) {
            std::this_thread::sleep_for(
                std::chrono::duration<double>(std::min(0.05, until_s - now)));
            tick();
        }
    }

  private:
    // The reference caches' images, pyramids and the temporaries of building them, per pixel of
    // a reference: about 8 bytes, and 4 more for a heat map (docs/benchmarks.md, "Page faults
    // on a reference's first load").
    std::size_t referenceCacheBytes() const {
        const auto& camera = db_->info().ceiling_camera;
        const bool heat_maps = refiner_options_.sampler.mode != refine::SamplingMode::Grid;
        return options_.image_cache_capacity * camera.ncols * camera.nrows * (heat_maps ? 12 : 8);
    }

    /// The first refined frame since the last kidnapping closes its count.
    void countColdStart(const FrameResult& frame) {
        if (timing_.cold_start_frames.empty() || timing_.cold_start_frames.back() >= 0) return;
        ++frames_since_kidnap_;
        if (frame.status == FrameStatus::Refined) {
            timing_.cold_start_frames.back() = frames_since_kidnap_ - 1;
            frames_since_kidnap_ = 0;
        }
    }

    std::size_t feedItems(std::vector<SensorClock::Item> items) {
        std::size_t frames = 0;
        for (auto& item : items) {
            const double late_s = options_.realtime ? std::max(0.0, elapsed() - item.arrival_s) : 0;
            frames += feed(item.obs, late_s, item.record) ? 1 : 0;
        }
        return frames;
    }

    bool feedLocalizer(const mrpt::obs::CObservation::Ptr& obs, double late_s,
                       double arrival_unix_s, std::size_t record) {
        const bool is_ceiling = obs->sensorLabel == options_.ceiling_camera_label;
        const auto* img = dynamic_cast<const mrpt::obs::CObservationImage*>(obs.get());
        if (is_ceiling && img != nullptr && options_.realtime && late_s > options_.max_latency_s) {
            const auto frame = localizer_->dropped(*img);
            writer_->write(frame, img);
            link_->frame(frame, timing_.frames, arrival_unix_s, wall_.Tac());
            ++timing_.frames;
            ++timing_.frames_dropped;
            return true;
        }
        if (is_ceiling && req_.kidnap_every > 0 &&
            timing_.frames % static_cast<std::size_t>(req_.kidnap_every) == 0) {
            if (timing_.frames > 0) localizer_->restart();  // the first frame starts cold anyway
            timing_.cold_start_frames.push_back(-1);
            frames_since_kidnap_ = 0;
        }
        const auto frame = localizer_->process(obs);
        if (auto rejected = localizer_->takeRejection()) skip(*obs, *rejected, record);
        if (!frame) return false;
        countColdStart(*frame);
        writer_->write(*frame, img);
        link_->frame(*frame, timing_.frames, arrival_unix_s, wall_.Tac());
        if (img != nullptr) img->image.unload();  // keep memory flat on long runs
        ++timing_.frames;
        timing_.coarse_ms += frame->times.coarse_ms;
        timing_.select_ms += frame->times.select_ms;
        timing_.refine_ms += frame->times.refine_ms;
        timing_.place_ms += frame->times.place_ms;
        timing_.total_ms += frame->times.total_ms;
        if (frame->refinement) {
            const auto& t = frame->refinement->times;
            timing_.refine_stage_ms["select"] += t.select_ms;
            timing_.refine_stage_ms["match"] += t.match_ms;
            timing_.refine_stage_ms["homography"] += t.homography_ms;
            timing_.refine_stage_ms["estimate"] += t.estimate_ms;
        }
        return true;
    }

  public:
    void progress(std::size_t expected) const {
        if (!req_.progress || !isatty(STDERR_FILENO)) return;
        if (timing_.frames % 10 != 0 && timing_.frames != expected) return;
        std::cerr << "\r"
                  << (expected ? mrpt::system::progress(double(timing_.frames) / expected, 40)
                               : std::string())
                  << " " << timing_.frames << (expected ? "/" + std::to_string(expected) : "")
                  << " frames, " << timing_.frames_dropped << " dropped" << std::flush;
    }

    /// The vehicle jumped (--repeat): the localiser starts again as at the first frame.
    void restart() { localizer_->restart(); }

    bool done() const { return req_.max_frames > 0 && timing_.frames >= req_.max_frames; }

    RunTiming finish() {
        if (req_.progress && isatty(STDERR_FILENO)) std::cerr << "\n";
        for (const auto& [kind, n] : timing_.skipped) {
            std::cerr << "lookup-localize: warning: " << source_ << ": " << n
                      << " observation(s) skipped: " << kind << "\n";
        }
        reportOnlineRefresh();
        reportCameraClock();
        reportReadout();
        reportLens();
        saveCameraClock();
        timing_.wall_s = wall_.Tac();
        writer_->finish(timing_);
        link_->finish(writer_->directory(), wall_.Tac());
        finished_ = true;
        return timing_;
    }

  private:
    /// The camera clock carried from the vehicle's earlier runs (camera_clock_file).
    void startCameraClock(const std::string& file) {
        if (file.empty() || !options_.camera_clock.enabled) return;
        if (!surveyClockKnown(options_, db_->info())) {
            std::cerr << "lookup-localize: " << file
                      << ": not carried (neither read nor written): the database's survey "
                         "camera clock is not known (db.ini ceiling_time_offset_sigma_s)\n";
            return;
        }
        camera_clock_file_ = file;
        std::string why_not;
        const auto saved = readCameraClockFile(file, options_.ceiling_camera_label, why_not);
        if (!saved) {
            std::cerr << "lookup-localize: " << why_not << "; the estimate starts afresh\n";
            return;
        }
        localizer_->carryCameraClock(saved->estimate);
        std::cerr << "lookup-localize: ceiling camera's time offset carried from " << file << ": "
                  << offsetText(saved->estimate) << "\n";
    }

    static std::string millisecondsText(double value_s, double sigma_s) {
        char text[64];
        std::snprintf(text, sizeof text, "%+.1f +- %.1f ms", 1e3 * value_s, 1e3 * sigma_s);
        return text;
    }

    static std::string offsetText(const CameraClock::Estimate& e) {
        return millisecondsText(e.offset_s, e.sigma_s) + " from " + std::to_string(e.pairs) +
               " pairs of fixes";
    }

    void reportCameraClock() {
        const auto& clock = localizer_->cameraClock();
        if (const auto& c = clock.carried()) {
            timing_.camera_time_offset["carried_s"] = c->offset_s;
            timing_.camera_time_offset["carried_sigma_s"] = c->sigma_s;
        }
        if (clock.carriedDropped()) timing_.camera_time_offset["carried_dropped"] = 1;
        if (!clock.estimate()) return;
        const auto& e = *clock.estimate();
        timing_.camera_time_offset["estimate_s"] = e.offset_s;
        timing_.camera_time_offset["sigma_s"] = e.sigma_s;
        timing_.camera_time_offset["pairs"] = double(e.pairs);
        timing_.camera_time_offset["applied_s"] = clock.applied();
        if (const auto& speed = clock.speedEstimate()) {
            timing_.camera_time_offset["speed_changes_s"] = speed->offset_s;
            timing_.camera_time_offset["speed_changes_sigma_s"] = speed->sigma_s;
        }
        if (clock.unappliedOffset() > 0) {
            timing_.camera_time_offset["unapplied_s"] = clock.unappliedOffset();
        }
        std::cerr << "lookup-localize: ceiling camera's time offset against the odometry: "
                  << offsetText(e) << (clock.carried() ? " (carried ones included); " : "; ")
                  << cameraClockOutcome(clock) << "\n";
    }

    /// What became of the estimate, for the run's last line about the camera clock.
    static std::string cameraClockOutcome(const CameraClock& clock) {
        std::ostringstream out;
        if (clock.carriedDropped())
            out << "the carried estimate dropped (this drive's disagrees); ";
        out << (!clock.applies()    ? "reported only (apply_camera_time_offset)"
                : clock.isApplied() ? "applied"
                : clock.unappliedAsOdometryLateness()
                    ? "not applied (the odometry is the later: its own lateness)"
                    : "not applied (not precise and significant)");
        const double survey_ms = std::round(1e4 * clock.contamination()) / 10;
        if (survey_ms > 0 && clock.applies()) {
            out << " beside the survey camera's unknown lateness (+- " << survey_ms
                << " ms, db.ini)";
        }
        if (const auto& speed = clock.speedEstimate()) {
            out << "; from its speed changes " << millisecondsText(speed->offset_s, speed->sigma_s);
        }
        if (clock.unappliedOffset() > 0) {
            out << "; every pose's covariance carries "
                << std::round(1e4 * clock.unappliedOffset()) / 10 << " ms";
        }
        return out.str();
    }

    void reportLens() {
        const auto& lens = localizer_->lens();
        if (lens.imagesAdded() < static_cast<std::size_t>(lens.options().frames)) return;
        timing_.lens = {{"images", double(lens.imagesAdded())},
                        {"dirty_share", lens.dirtyShare()},
                        {"least_transmission", lens.leastTransmission()},
                        {"corrected", lens.dirty() ? 1.0 : 0.0}};
        if (!lens.dirty()) return;
        std::cerr << "lookup-localize: "
                  << refine::dirtyLensWarning(lens.dirtyShare(), lens.leastTransmission(),
                                              lens.options(), "each image")
                  << "\n";
    }

    void reportReadout() {
        const auto& r = localizer_->readoutEstimator();
        if (!r.estimate()) return;
        const auto& e = *r.estimate();
        timing_.readout = {{"query_s", e.query_s},
                           {"query_sigma_s", e.query_sigma_s},
                           {"survey_s", e.survey_s},
                           {"survey_sigma_s", e.survey_sigma_s},
                           {"frames", double(e.frames)},
                           {"query_applied_s", r.queryReadout()},
                           {"survey_applied_s", r.surveyReadout()}};
        const auto outcome = [](bool applied, double modelled_s, bool applies,
                                const char* why_not) {
            if (applied) return std::string("applied");
            if (modelled_s > 0)
                return std::string("configured: ") +
                       std::to_string(int(std::round(1e3 * modelled_s))) + " ms kept";
            return std::string(applies ? why_not : "reported only (apply_estimated_readout)");
        };
        std::cerr << "lookup-localize: ceiling cameras' rolling-shutter readout from the rows of "
                  << e.frames << " refined frames: this vehicle's "
                  << millisecondsText(e.query_s, e.query_sigma_s) << ", "
                  << outcome(r.queryApplied(), r.queryReadout(), r.applies(),
                             "not applied (not precise and significant, or the survey's not "
                             "bounded under half of it)")
                  << "; the survey's " << millisecondsText(e.survey_s, e.survey_sigma_s) << ", "
                  << outcome(r.surveyApplied(), r.surveyReadout(), r.applies(),
                             r.appliesSurvey() ? "not applied (not precise and significant)"
                                               : "reported only (the survey camera clock is not "
                                                 "known)")
                  << "\n";
    }

    /// Writes the estimate for the vehicle's next run (camera_clock_file); a failure is said,
    /// not fatal.
    void saveCameraClock() {
        const auto& e = localizer_->cameraClock().estimate();
        if (camera_clock_file_.empty() || !e) return;
        try {
            writeCameraClockFile(camera_clock_file_,
                                 {options_.ceiling_camera_label, *e, PoseStream::unixTime()});
            timing_.camera_time_offset["written"] = 1;
        } catch (const std::exception& ex) {
            std::cerr << "lookup-localize: warning: camera clock not carried: " << ex.what()
                      << "\n";
        }
    }

    void reportOnlineRefresh() {
        if (!localizer_->options().online_refresh) return;
        const auto& r = localizer_->onlineRefresh();
        timing_.online_refresh = {{"stretches", r.stretches},
                                  {"stretches_refused", r.refused},
                                  {"references_added", r.references},
                                  {"references_superseded", r.superseded}};
        if (r.stretches + r.refused == 0) return;
        std::cerr << "lookup-localize: online refresh: " << r.stretches
                  << " changed stretch(es) bridged (" << r.refused << " left alone), "
                  << r.references << " references added in memory, " << r.superseded
                  << " superseded\n";
    }

    /// Counts a refused observation and names it on stderr (the first few of each kind).
    void skip(const mrpt::obs::CObservation& obs, const Rejection& why, std::size_t record) {
        constexpr std::size_t kWarningsPerKind = 5;
        const std::size_t n = ++timing_.skipped[why.kind];
        if (n > kWarningsPerKind) return;
        std::cerr << "lookup-localize: warning: " << source_
                  << (record == std::string::npos ? " '" + obs.sensorLabel + "'"
                                                  : ": record " + std::to_string(record))
                  << ": " << why.detail << ": skipped (" << why.kind << ")"
                  << (n == kWarningsPerKind ? "; further ones are only counted" : "") << "\n";
    }

    const LocalizeRequest& req_;
    std::string source_;
    LocalizerOptions options_;
    refine::RefinerOptions refiner_options_;
    coarse::CoarseOptions coarse_options_;
    place::PlaceIndexOptions place_options_;
    std::unique_ptr<database::ReferenceDatabase> db_;
    std::unique_ptr<place::PlaceIndex> places_;  ///< before localizer_, which uses it
    int frames_since_kidnap_ = 0;
    std::unique_ptr<Localizer> localizer_;
    std::unique_ptr<RunWriter> writer_;
    bool finished_ = false;
    QuerySpan span_;
    SensorClock clock_;
    std::string camera_clock_file_;  ///< carried between runs; "" = not (startCameraClock)
    std::unique_ptr<VehicleLink> link_;
    RunTiming timing_;
    mrpt::system::CTicTac wall_;
};

}  // namespace

void requestStop() { stop_requested = true; }

RunTiming runLocalization(const LocalizeRequest& req) {
    if (req.repeat < 1) throw common::ConfigError("--repeat must be >= 1");
    stop_requested = false;
    Session session(req, req.rawlog);
    const auto& options = session.options();
    const std::size_t expected = session.expectedFrames();
    PassShift shift;
    double clock_shift_s = 0;                       // realtime replay across clock jumps
    std::map<std::string, double> last_arrival_of;  // per sensor
    for (int pass = 0; pass < req.repeat && !session.done() && !stop_requested; ++pass) {
        if (pass > 0) {
            session.flushClock();
            shift.nextPass();
            session.restart();  // the vehicle jumped back to the start
            last_arrival_of.clear();
        }
        common::RawlogReader reader(req.rawlog);
        mrpt::obs::CObservation::Ptr obs;
        while (!stop_requested && reader.next(obs)) {
            const double stamp = shift.apply(*obs);
            const double first_stamp = shift.firstStamp();
            double late_s = 0, arrival_s = 0;
            if (options.realtime) {
                // The observation arrives at its recorded time (relative to the first one); a
                // sensor clock that jumps back (reported by the health checks) shifts the
                // replay clock by the jump, so later frames are not all late.
                double arrival = stamp - first_stamp + clock_shift_s;
                auto& previous = last_arrival_of[obs->sensorLabel];
                if (arrival < previous) {
                    clock_shift_s += previous - arrival;
                    arrival = previous;
                }
                previous = arrival;
                arrival_s = arrival;
                const double now = session.elapsed();
                session.sleepUntil(arrival);
                late_s = std::max(0.0, now - arrival);
            }
            try {
                if (session.feedClocked(obs, late_s, arrival_s, reader.recordIndex()) == 0) {
                    continue;
                }
            } catch (const common::WriteError&) {
                throw;  // the output's fault, not the rawlog's
            } catch (const std::exception& e) {
                throw common::RawlogError(req.rawlog, reader.recordIndex(), e.what());
            }
            session.progress(expected * static_cast<std::size_t>(req.repeat));
            if (session.done()) break;
        }
    }
    if (!stop_requested && !session.done()) session.flushClock();
    return session.finish();
}

namespace {

// One live sensor of a rawlog-grabber style .ini, polled at its process_rate.
struct LiveSensor {
    std::string section;
    mrpt::hwdrivers::CGenericSensor::Ptr driver;
    std::optional<mrpt::img::TCamera> camera;  ///< camera_params_file: live calibration
    double period_s = 0.01;
    double next_s = 0;
};

// The sensor of `section` (with a non-empty `driver`), configured and initialised.
LiveSensor openSensor(const mrpt::config::CConfigFile& ini, const std::string& section,
                      const std::string& driver, const std::string& sensors_ini) {
    LiveSensor s;
    s.section = section;
    s.driver = mrpt::hwdrivers::CGenericSensor::createSensorPtr(driver);
    if (!s.driver) {
        throw common::ConfigError(sensors_ini + " [" + section + "] driver: unknown " +
                                  "sensor class '" + driver + "'");
    }
    try {
        s.driver->loadConfig(ini, section);
        s.camera = common::sensorCameraParams(ini, section, sensors_ini);
        s.driver->initialize();
        const std::string recorded = ini.read_string(section, "rawlog_file", "", false);
        if (ini.read_string(section, "grabber_type", "", false) == "rawlog" && !recorded.empty()) {
            // MRPT 2.5.8 drops the '/' before <name>_Images for absolute rawlog paths;
            // point external images at the right folder ourselves.
            mrpt::img::CImage::setImagesPathBase(common::imagesDirectoryFor(recorded));
        }
    } catch (const std::exception& e) {
        throw common::ConfigError(sensors_ini + " [" + section + "]: " + e.what());
    }
    s.period_s = 1.0 / std::max(1e-3, ini.read_double(section, "process_rate", 100, false));
    return s;
}

// Every section of the .ini with a `driver` key; refuses an .ini without one.
std::vector<LiveSensor> openSensors(const std::string& sensors_ini) {
    mrpt::config::CConfigFile ini(sensors_ini);
    std::vector<std::string> sections;
    ini.getAllSections(sections);
    std::vector<LiveSensor> sensors;
    for (const auto& section : sections) {
        const std::string driver = ini.read_string(section, "driver", "", false);
        if (!driver.empty()) sensors.push_back(openSensor(ini, section, driver, sensors_ini));
    }
    if (sensors.empty()) {
        throw common::ConfigError(sensors_ini + ": no section with a 'driver' key");
    }
    return sensors;
}

// Polls one sensor into `arrived`. A sensor that fails (unplugged camera, end of a recorded
// stream) is closed; the others go on, and the run ends when all are quiet.
void pollSensor(LiveSensor& s, const std::string& sensors_ini,
                mrpt::hwdrivers::CGenericSensor::TListObservations& arrived) {
    try {
        s.driver->doProcess();
    } catch (const std::exception& e) {
        std::cerr << "lookup-localize: " << sensors_ini << " [" << s.section
                  << "]: sensor stopped: " << mrpt::exception_to_str(e).substr(0, 200) << "\n";
        s.driver.reset();
        return;
    }
    mrpt::hwdrivers::CGenericSensor::TListObservations got;
    s.driver->getObservations(got);
    for (auto& [stamp, object] : got) {
        auto obs = std::dynamic_pointer_cast<mrpt::obs::CObservation>(object);
        if (s.camera && obs) common::applyCameraParams(*s.camera, *obs);
    }
    arrived.insert(got.begin(), got.end());
}

// What every sensor that is due at `now` delivers, in time order.
mrpt::hwdrivers::CGenericSensor::TListObservations pollDue(std::vector<LiveSensor>& sensors,
                                                           double now,
                                                           const std::string& sensors_ini) {
    mrpt::hwdrivers::CGenericSensor::TListObservations arrived;
    for (auto& s : sensors) {
        if (!s.driver || now < s.next_s) continue;
        s.next_s = now + s.period_s;
        pollSensor(s, sensors_ini, arrived);
    }
    return arrived;
}

// Hands one polled batch to the session; lateness is the time since the batch was polled,
// i.e. spent on earlier observations.
void feedBatch(Session& session, const mrpt::hwdrivers::CGenericSensor::TListObservations& arrived,
               double polled_s) {
    for (const auto& [stamp, object] : arrived) {
        auto obs = std::dynamic_pointer_cast<mrpt::obs::CObservation>(object);
        if (!obs) continue;
        session.feedClocked(obs, session.elapsed() - polled_s, polled_s);
        session.progress(0);
        if (session.done()) break;
    }
}

}  // namespace

RunTiming runLiveLocalization(const LiveRequest& live) {
    LocalizeRequest req = live.base;
    req.realtime = 1;
    stop_requested = false;
    std::vector<LiveSensor> sensors = openSensors(live.sensors_ini);
    Session session(req, live.sensors_ini);
    double last_data_s = 0;
    while (!session.done() && !stop_requested) {
        const double now = session.elapsed();
        if (live.duration_s > 0 && now > live.duration_s) break;
        if (now - last_data_s > live.quiet_timeout_s) break;
        const auto arrived = pollDue(sensors, now, live.sensors_ini);
        if (arrived.empty()) {
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
            session.tick();  // a stopped camera is noticed while nothing arrives
            continue;
        }
        last_data_s = now;
        feedBatch(session, arrived, now);
    }
    if (!stop_requested) session.flushClock();
    return session.finish();
}

std::string defaultMethodName(const refine::RefinerOptions& o, bool database_has_heat_maps) {
    switch (o.correspondence.method) {
        case refine::CorrespondenceMethod::Orb:
            return "lookup-orb";
        case refine::CorrespondenceMethod::Ecc:
            return "lookup-ecc";
        case refine::CorrespondenceMethod::Sad:
            break;
    }
    const bool heat = o.sampler.mode == refine::SamplingMode::HeatMap ||
                      (o.sampler.mode == refine::SamplingMode::Auto && database_has_heat_maps);
    return heat ? "lookup-fcn" + std::to_string(o.sampler.heat_map_points)
                : "lookup-grid" + std::to_string(o.sampler.grid_points);
}

}  // namespace lookup::localize
