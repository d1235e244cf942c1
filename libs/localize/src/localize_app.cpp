#include "lookup/localize/localize_app.h"

#include <mrpt/config/CConfigFile.h>
#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/system/CTicTac.h>
#include <mrpt/system/progress.h>

#include <unistd.h>
#include <chrono>
#include <iostream>
#include <thread>

#include "lookup/coarse/coarse_source.h"
#include "lookup/common/config.h"
#include "lookup/common/rawlog_io.h"

namespace lookup::localize {

namespace {

std::size_t countFrames(const std::string& rawlog, const std::string& label) {
    common::RawlogReader reader(rawlog);
    mrpt::obs::CObservation::Ptr obs;
    std::size_t n = 0;
    while (reader.next(obs)) n += obs->sensorLabel == label;
    return n;
}

}  // namespace

RunTiming runLocalization(const LocalizeRequest& req) {
    // Options: defaults, then the ini file, then command-line overrides.
    LocalizerOptions options;
    refine::RefinerOptions refiner_options;
    coarse::CoarseOptions coarse_options;
    if (!req.ini_file.empty()) {
        mrpt::config::CConfigFile ini(req.ini_file);
        if (ini.sectionExists("localizer")) options.loadFromConfigFile(ini, "localizer");
        refiner_options.loadFromConfigFile(ini, "refine");
        if (ini.sectionExists("coarse")) coarse_options.loadFromConfigFile(ini, "coarse");
    }
    if (req.realtime >= 0) options.realtime = req.realtime == 1;
    if (req.sampling == "grid") refiner_options.sampler.mode = refine::SamplingMode::Grid;
    if (req.sampling == "heatmap") refiner_options.sampler.mode = refine::SamplingMode::HeatMap;
    options.check();
    refiner_options.check();

    const auto db = database::ReferenceDatabase::load(req.db_dir, options.image_cache_capacity);
    if (req.sampling == "heatmap" && db.info().heatmaps_dir.empty()) {
        throw std::runtime_error(req.db_dir + "/db.ini: no heat maps (run lookup-train first)");
    }
    std::unique_ptr<coarse::CoarseSource> coarse;
    if (!req.coarse_matches.empty()) {
        coarse = std::make_unique<coarse::MatchFileSource>(req.coarse_matches, 1.0);
    } else if (!req.coarse_poses.empty()) {
        coarse = std::make_unique<coarse::PoseFileSource>(req.coarse_poses, 1.0);
    } else {
        coarse = makeSequenceCoarseSource(db, coarse_options, options.coarse_traverse);
    }
    const bool coarse_from_files = !req.coarse_matches.empty() || !req.coarse_poses.empty();
    Localizer localizer(db, options, refiner_options, std::move(coarse), !coarse_from_files);

    mrpt::config::CConfigFileMemory used;
    used.write("run", "method", req.method);
    used.write("run", "db", req.db_dir);
    used.write("run", "rawlog", req.rawlog);
    options.saveToConfigFile(used, "localizer");
    refiner_options.saveToConfigFile(used, "refine");
    coarse_options.saveToConfigFile(used, "coarse");
    std::string used_text;
    used.getContent(used_text);
    RunWriter writer(req.out_dir, used_text, options.write_debug_images, options.debug_image_every);

    const std::size_t expected = countFrames(req.rawlog, options.ceiling_camera_label);
    if (expected == 0) {
        throw common::RawlogError(
            req.rawlog, "no '" + options.ceiling_camera_label + "' images: nothing to localise");
    }
    const bool show_progress = req.progress && isatty(STDERR_FILENO);

    RunTiming timing;
    common::RawlogReader reader(req.rawlog);
    mrpt::obs::CObservation::Ptr obs;
    mrpt::system::CTicTac wall;
    double first_stamp = -1;
    double last_stamp = -1;
    while (reader.next(obs)) {
        const double stamp = mrpt::Clock::toDouble(obs->timestamp);
        if (first_stamp < 0) first_stamp = stamp;
        const bool is_ceiling = obs->sensorLabel == options.ceiling_camera_label;
        if (is_ceiling && stamp <= last_stamp) {
            throw common::RawlogError(req.rawlog, reader.recordIndex(),
                                      "ceiling image time stamps go backwards");
        }
        if (options.realtime) {
            // Observation arrives at its recorded time; a ceiling frame that cannot be started
            // within max_latency_s of its arrival is dropped, as on the vehicle.
            const double arrival = stamp - first_stamp;
            const double now = wall.Tac();
            if (now < arrival) {
                std::this_thread::sleep_for(std::chrono::duration<double>(arrival - now));
            } else if (is_ceiling && now - arrival > options.max_latency_s) {
                const auto* img = dynamic_cast<const mrpt::obs::CObservationImage*>(obs.get());
                writer.write(localizer.dropped(*img), img);
                ++timing.frames;
                ++timing.frames_dropped;
                last_stamp = stamp;
                continue;
            }
        }
        std::optional<FrameResult> frame;
        try {
            frame = localizer.process(obs);
        } catch (const std::exception& e) {
            throw common::RawlogError(req.rawlog, reader.recordIndex(), e.what());
        }
        if (!frame) continue;
        last_stamp = stamp;
        const auto* img = dynamic_cast<const mrpt::obs::CObservationImage*>(obs.get());
        writer.write(*frame, img);
        if (img != nullptr) img->image.unload();  // keep memory flat on long replays
        ++timing.frames;
        timing.coarse_ms += frame->times.coarse_ms;
        timing.select_ms += frame->times.select_ms;
        timing.refine_ms += frame->times.refine_ms;
        timing.total_ms += frame->times.total_ms;
        if (frame->refinement) {
            const auto& t = frame->refinement->times;
            timing.refine_stage_ms["select"] += t.select_ms;
            timing.refine_stage_ms["match"] += t.match_ms;
            timing.refine_stage_ms["homography"] += t.homography_ms;
            timing.refine_stage_ms["estimate"] += t.estimate_ms;
        }
        if (show_progress && (timing.frames % 10 == 0 || timing.frames == expected)) {
            std::cerr << "\r" << mrpt::system::progress(double(timing.frames) / expected, 40) << " "
                      << timing.frames << "/" << expected << " frames" << std::flush;
        }
        if (req.max_frames > 0 && timing.frames >= req.max_frames) break;
    }
    if (show_progress) std::cerr << "\n";
    timing.wall_s = wall.Tac();
    writer.finish(timing);
    return timing;
}

}  // namespace lookup::localize
