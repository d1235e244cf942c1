#pragma once
// lookup-localize as a library class (thin main in apps/lookup-localize), so tests run it.
//   lookup-localize --db DB (--rawlog QUERY.rawlog | --live SENSORS.ini) --out RUN_DIR
//                   [--ini FILE] [--method NAME]
//                   [--coarse-matches F | --coarse-poses F] [--sampling grid|heatmap|auto]
//                   [--matcher sad|orb|ecc]
//                   [--realtime] [--max-frames N] [--repeat N] [--kidnap-every N]
//                   [--publish udp://HOST:PORT | tcp://HOST:PORT] [--persist-fix FILE]

#include <string>

#include "lookup/common/app.h"
#include "lookup/localize/run_writer.h"
#include "lookup/refine/options.h"

namespace lookup::localize {

struct LocalizeRequest {
    std::string db_dir;          ///< reference database (lookup-survey)
    std::string rawlog;          ///< query rawlog to replay
    std::string out_dir;         ///< run folder (docs/run-format.md)
    std::string ini_file;        ///< optional: [localizer], [refine.*], [coarse] sections
    std::string method;          ///< name of the method in run.ini and the eval report;
                                 ///< empty: named after the options (defaultMethodName)
    std::string coarse_matches;  ///< optional: `query_time reference_time` file
    std::string coarse_poses;    ///< optional: coarse poses (TUM / MRPT)
    std::string sampling;        ///< optional override: "grid", "heatmap" or "auto"
    std::string matcher;         ///< optional override of [refine.correspondence] method:
                                 ///< "sad", "orb" or "ecc" (ORB / ECC baselines)
    int realtime = -1;           ///< -1: from the ini; 0: as fast as possible; 1: recorded rate
    std::size_t max_frames = 0;  ///< stop after this many ceiling frames (0 = all)
    /// Replays the rawlog this many times, each pass's time stamps after the previous one's
    /// (long-run memory and throughput checks: the vehicle jumps back to the start).
    int repeat = 1;
    /// Every this many ceiling frames the localiser is restarted (Localizer::restart: a
    /// kidnapping, the vehicle moved while off), so one replay measures cold starts all along
    /// the route; timing.json "cold_starts" counts the frames each took to its first fix. 0 = none.
    int kidnap_every = 0;
    bool progress = true;  ///< progress bar on stderr when it is a terminal

    // On the vehicle (docs/run-format.md): pose stream, restarts.
    std::string publish;      ///< "udp://HOST:PORT" or "tcp://HOST:PORT" (--publish); "" = none
    std::string persist_fix;  ///< fix file (--persist-fix); "" = [localizer] persist_fix_file
    /// camera clock file (--camera-clock); "" = [localizer] camera_clock_file
    std::string camera_clock;
    /// tcp: wait up to this long for a first client before the first frame (tests) [s].
    double publish_wait_s = 0;
};

/// The report's name of a LookUP run without --method: "lookup-grid24", "lookup-fcn12" (heat
/// maps; Auto with a database that has them), "lookup-orb" or "lookup-ecc" (baselines).
std::string defaultMethodName(const refine::RefinerOptions& options, bool database_has_heat_maps);

/// Live sensors, configured as for MRPT's rawlog-grabber: every section of `sensors_ini` with
/// a `driver` key (e.g. `driver = CCameraSensor`) is created through
/// mrpt::hwdrivers::CGenericSensor and polled at its `process_rate`.
struct LiveRequest {
    LocalizeRequest base;        ///< db_dir, out_dir, ini_file, method, coarse files, sampling
    std::string sensors_ini;     ///< rawlog-grabber style sensor configuration
    double duration_s = 0;       ///< stop after this long (0 = until the sensors go quiet)
    double quiet_timeout_s = 5;  ///< stop when no sensor delivered anything for this long
};

/// Asks a running runLocalization / runLiveLocalization to stop after the current frame and to
/// finish its run folder as at the end (timing.json, the persisted fix, the stream closed).
/// Async-signal-safe: lookup-localize calls it on SIGINT and SIGTERM. Each run clears it at start.
void requestStop();

/// Runs the localiser over a rawlog. Returns the run's timing. Throws std::runtime_error (or
/// a subclass) naming the file, record and reason for bad input; frames already processed stay
/// written in the run folder.
RunTiming runLocalization(const LocalizeRequest& request);

/// Runs the localiser on live sensors (always real time: late frames are dropped). Throws
/// naming the file and section for a sensor that cannot be created or initialised.
RunTiming runLiveLocalization(const LiveRequest& request);

/// The first SIGINT / SIGTERM (Ctrl-C, systemctl stop) calls requestStop, so the run ends as at
/// its end (the fix persisted, the run folder complete); a second one kills at once.
void stopOnSignals();

/// lookup-localize: the command line into a LocalizeRequest (or a LiveRequest with --live),
/// then runLocalization / runLiveLocalization and the one-line timing summary on stdout.
/// Errors of the run itself (the --ini file, the database, the rawlog) escape run() for
/// common::runApp to report.
class LocalizeApp : public common::App {
  public:
    bool initialize(int argc, const char* const* argv) override;
    int run() override;

    const LocalizeRequest& request() const { return request_; }
    bool live() const { return !sensors_ini_.empty(); }
    const RunTiming& timing() const { return timing_; }

  private:
    LocalizeRequest request_;
    std::string sensors_ini_;  ///< --live
    double duration_s_ = 0;    ///< --duration
    RunTiming timing_;
};

}  // namespace lookup::localize
