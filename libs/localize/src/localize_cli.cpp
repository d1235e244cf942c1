#include <mrpt/3rdparty/tclap/CmdLine.h>

#include <algorithm>
#include <csignal>
#include <cstdio>

#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/localize/localize_app.h"

namespace lookup::localize {
namespace {

void onStopSignal(int signal) {
    requestStop();
    std::signal(signal, SIG_DFL);
}

// What TCLAP cannot check: a frame count >= 0 and one source of frames.
void checkFlags(int max_frames, const std::string& rawlog, const std::string& sensors_ini) {
    if (max_frames < 0) {
        throw common::ConfigError("--max-frames " + std::to_string(max_frames) +
                                  ": must be >= 0 (0: every frame)");
    }
    if (rawlog.empty() == sensors_ini.empty()) {
        throw common::ConfigError("give exactly one of --rawlog FILE or --live FILE.ini");
    }
}

}  // namespace

void stopOnSignals() {
    std::signal(SIGINT, onStopSignal);
    std::signal(SIGTERM, onStopSignal);
}

bool LocalizeApp::initialize(int argc, const char* const* argv) {
    using TCLAP::SwitchArg;
    using TCLAP::ValueArg;
    TCLAP::CmdLine cmd(
        std::string("lookup-localize: LookUP precise localisation. ") + common::kExitCodesHelp, ' ',
        "0.1");
    ValueArg<std::string> db("", "db", "reference database folder", true, "", "DB", cmd);
    ValueArg<std::string> rawlog("", "rawlog", "query rawlog to replay", false, "", "FILE", cmd);
    ValueArg<std::string> live("", "live",
                               "live sensors, rawlog-grabber style .ini (sections "
                               "with driver = CCameraSensor, ...)",
                               false, "", "FILE", cmd);
    ValueArg<double> duration("", "duration", "live: stop after this many seconds", false, 0, "S",
                              cmd);
    ValueArg<std::string> out("", "out", "run output folder", true, "", "DIR", cmd);
    ValueArg<std::string> ini("", "ini", "options: [localizer] [refine.*] [coarse]", false, "",
                              "FILE", cmd);
    ValueArg<std::string> method(
        "", "method",
        "method name for the report (default: lookup-grid24, lookup-fcn12, lookup-orb, ... "
        "from the sampler and matcher used)",
        false, "", "NAME", cmd);
    ValueArg<std::string> matches("", "coarse-matches",
                                  "coarse stage from `query_t reference_t` rows", false, "", "FILE",
                                  cmd);
    ValueArg<std::string> poses("", "coarse-poses", "coarse stage from a pose file", false, "",
                                "FILE", cmd);
    ValueArg<std::string> sampling("", "sampling", "grid, heatmap or auto", false, "", "MODE", cmd);
    ValueArg<std::string> matcher("", "matcher",
                                  "correspondences: sad (LookUP), orb or ecc (OpenCV baselines); "
                                  "the method name defaults to lookup-orb / lookup-ecc",
                                  false, "", "sad|orb|ecc", cmd);
    SwitchArg realtime("", "realtime", "replay at the recorded rate, dropping late frames", cmd);
    ValueArg<int> max_frames("", "max-frames", "stop after N ceiling frames", false, 0, "N", cmd);
    ValueArg<int> repeat(
        "", "repeat",
        "replay the rawlog N times, each pass timed after the previous one (long runs)", false, 1,
        "N", cmd);
    ValueArg<int> kidnap_every("", "kidnap-every",
                               "restart the localiser every N ceiling frames (cold starts all "
                               "along the route; timing.json cold_starts)",
                               false, 0, "N", cmd);
    ValueArg<std::string> publish(
        "", "publish",
        "send every frame's pose and a health message per second as JSON: udp://HOST:PORT "
        "(one datagram each) or tcp://HOST:PORT (a server; one line each)",
        false, "", "URL", cmd);
    ValueArg<std::string> persist_fix(
        "", "persist-fix",
        "keep the last refined fix in FILE and start from it (the ceiling must confirm it)", false,
        "", "FILE", cmd);
    ValueArg<std::string> camera_clock(
        "", "camera-clock",
        "carry the ceiling camera's estimated time offset in FILE from run to run (read at the "
        "start, written at the end; against databases whose survey camera clock is known)",
        false, "", "FILE", cmd);
    SwitchArg verbose("", "verbose", "on errors, print MRPT's full exception dump", cmd);
    if (!parseCommandLine(cmd, argc, argv)) return false;

    LocalizeRequest& req = request_;
    req.db_dir = db.getValue();
    req.rawlog = rawlog.getValue();
    req.out_dir = out.getValue();
    req.ini_file = ini.getValue();
    req.matcher = matcher.getValue();
    req.method = method.getValue();
    req.coarse_matches = matches.getValue();
    req.coarse_poses = poses.getValue();
    req.sampling = sampling.getValue();
    if (realtime.getValue()) req.realtime = 1;
    req.repeat = repeat.getValue();
    req.kidnap_every = std::max(0, kidnap_every.getValue());
    req.publish = publish.getValue();
    req.persist_fix = persist_fix.getValue();
    req.camera_clock = camera_clock.getValue();
    sensors_ini_ = live.getValue();
    duration_s_ = duration.getValue();
    try {
        checkFlags(max_frames.getValue(), req.rawlog, sensors_ini_);
    } catch (const common::ConfigError& e) {
        return refuse("lookup-localize", e, verbose.getValue());
    }
    req.max_frames = static_cast<std::size_t>(max_frames.getValue());
    return true;
}

int LocalizeApp::run() {
    if (live()) {
        LiveRequest live_req;
        live_req.base = request_;
        live_req.sensors_ini = sensors_ini_;
        live_req.duration_s = duration_s_;
        timing_ = runLiveLocalization(live_req);
    } else {
        timing_ = runLocalization(request_);
    }
    const RunTiming& t = timing_;
    const double per_frame = double(std::max<std::size_t>(1, t.processed()));
    std::printf(
        "lookup-localize: %zu frames (%zu dropped) in %.1f s after %.1f s start-up: "
        "%.1f frames/s; %.2f ms/frame (coarse %.2f, select %.2f, refine %.2f) -> %s\n",
        t.frames, t.frames_dropped, t.wall_s, t.startup_s,
        t.wall_s > 0 ? t.processed() / t.wall_s : 0.0, t.total_ms / per_frame,
        t.coarse_ms / per_frame, t.select_ms / per_frame, t.refine_ms / per_frame,
        request_.out_dir.c_str());
    return exit_code_ = common::kExitOk;
}

}  // namespace lookup::localize
