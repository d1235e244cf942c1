// lookup-localize: precise localisation of a query rawlog against a reference database.
//   lookup-localize --db DB (--rawlog QUERY.rawlog | --live SENSORS.ini) --out RUN_DIR
//                   [--ini FILE] [--method NAME]
//                   [--coarse-matches F | --coarse-poses F] [--sampling grid|heatmap|auto]
//                   [--matcher sad|orb|ecc]
//                   [--realtime] [--max-frames N] [--repeat N] [--kidnap-every N]
//                   [--publish udp://HOST:PORT | tcp://HOST:PORT] [--persist-fix FILE]

#include <mrpt/3rdparty/tclap/CmdLine.h>

#include <csignal>
#include <cstdio>
#include <iostream>

#include "lookup/common/cli.h"
#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/localize/localize_app.h"

namespace {

// The first SIGINT / SIGTERM (Ctrl-C, systemctl stop) ends the run as at its end (the fix is
// persisted, the run folder complete); a second one kills at once.
void onStopSignal(int signal) {
    lookup::localize::requestStop();
    std::signal(signal, SIG_DFL);
}

int run(int argc, char** argv) {
    TCLAP::CmdLine cmd(std::string("lookup-localize: LookUP precise localisation. ") +
                           lookup::common::kExitCodesHelp,
                       ' ', "0.1");
    lookup::common::OneLineOutput one_line_errors;
    cmd.setOutput(&one_line_errors);
    TCLAP::ValueArg<std::string> db("", "db", "reference database folder", true, "", "DB", cmd);
    TCLAP::ValueArg<std::string> rawlog("", "rawlog", "query rawlog to replay", false, "", "FILE",
                                        cmd);
    TCLAP::ValueArg<std::string> live("", "live",
                                      "live sensors, rawlog-grabber style .ini (sections "
                                      "with driver = CCameraSensor, ...)",
                                      false, "", "FILE", cmd);
    TCLAP::ValueArg<double> duration("", "duration", "live: stop after this many seconds", false, 0,
                                     "S", cmd);
    TCLAP::ValueArg<std::string> out("", "out", "run output folder", true, "", "DIR", cmd);
    TCLAP::ValueArg<std::string> ini("", "ini", "options: [localizer] [refine.*] [coarse]", false,
                                     "", "FILE", cmd);
    TCLAP::ValueArg<std::string> method(
        "", "method",
        "method name for the report (default: lookup-grid24, lookup-fcn12, lookup-orb, ... "
        "from the sampler and matcher used)",
        false, "", "NAME", cmd);
    TCLAP::ValueArg<std::string> matches("", "coarse-matches",
                                         "coarse stage from `query_t reference_t` rows", false, "",
                                         "FILE", cmd);
    TCLAP::ValueArg<std::string> poses("", "coarse-poses", "coarse stage from a pose file", false,
                                       "", "FILE", cmd);
    TCLAP::ValueArg<std::string> sampling("", "sampling", "grid, heatmap or auto", false, "",
                                          "MODE", cmd);
    TCLAP::ValueArg<std::string> matcher(
        "", "matcher",
        "correspondences: sad (LookUP), orb or ecc (OpenCV baselines); the method name "
        "defaults to lookup-orb / lookup-ecc",
        false, "", "sad|orb|ecc", cmd);
    TCLAP::SwitchArg realtime("", "realtime",
                              "replay at the recorded rate, dropping late "
                              "frames",
                              cmd);
    TCLAP::ValueArg<int> max_frames("", "max-frames", "stop after N ceiling frames", false, 0, "N",
                                    cmd);
    TCLAP::ValueArg<int> repeat(
        "", "repeat",
        "replay the rawlog N times, each pass timed after the previous one (long runs)", false, 1,
        "N", cmd);
    TCLAP::ValueArg<int> kidnap_every(
        "", "kidnap-every",
        "restart the localiser every N ceiling frames (cold starts all along the route; "
        "timing.json cold_starts)",
        false, 0, "N", cmd);
    TCLAP::ValueArg<std::string> publish(
        "", "publish",
        "send every frame's pose and a health message per second as JSON: udp://HOST:PORT "
        "(one datagram each) or tcp://HOST:PORT (a server; one line each)",
        false, "", "URL", cmd);
    TCLAP::ValueArg<std::string> persist_fix(
        "", "persist-fix",
        "keep the last refined fix in FILE and start from it (the ceiling must confirm it)", false,
        "", "FILE", cmd);
    TCLAP::SwitchArg verbose("", "verbose", "on errors, print MRPT's full exception dump", cmd);
    if (!cmd.parse(argc, argv)) return lookup::common::parseFailureExitCode(argc, argv);

    lookup::localize::LocalizeRequest req;
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
    if (max_frames.getValue() < 0) {
        throw lookup::common::ConfigError("--max-frames " + std::to_string(max_frames.getValue()) +
                                          ": must be >= 0 (0: every frame)");
    }
    req.max_frames = static_cast<std::size_t>(max_frames.getValue());
    req.repeat = repeat.getValue();
    req.kidnap_every = std::max(0, kidnap_every.getValue());
    req.publish = publish.getValue();
    req.persist_fix = persist_fix.getValue();

    if (rawlog.getValue().empty() == live.getValue().empty()) {
        throw lookup::common::ConfigError("give exactly one of --rawlog FILE or --live FILE.ini");
    }
    lookup::localize::RunTiming t;
    if (!live.getValue().empty()) {
        lookup::localize::LiveRequest live_req;
        live_req.base = req;
        live_req.sensors_ini = live.getValue();
        live_req.duration_s = duration.getValue();
        t = lookup::localize::runLiveLocalization(live_req);
    } else {
        t = lookup::localize::runLocalization(req);
    }
    std::printf(
        "lookup-localize: %zu frames (%zu dropped) in %.1f s after %.1f s start-up: "
        "%.1f frames/s; %.2f ms/frame (coarse %.2f, select %.2f, refine %.2f) -> %s\n",
        t.frames, t.frames_dropped, t.wall_s, t.startup_s,
        t.wall_s > 0 ? t.processed() / t.wall_s : 0.0,
        t.total_ms / std::max<std::size_t>(1, t.processed()),
        t.coarse_ms / std::max<std::size_t>(1, t.processed()),
        t.select_ms / std::max<std::size_t>(1, t.processed()),
        t.refine_ms / std::max<std::size_t>(1, t.processed()), req.out_dir.c_str());
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    std::signal(SIGINT, onStopSignal);
    std::signal(SIGTERM, onStopSignal);
    return lookup::common::guardedMain("lookup-localize", argc, argv,
                                       [&] { return run(argc, argv); });
}
