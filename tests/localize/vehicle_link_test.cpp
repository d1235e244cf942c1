// What the vehicle gets from lookup-localize besides the run folder: the pose stream
// (--publish), health messages, and restarts from a persisted fix (--persist-fix).

#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <thread>

#include "lookup/common/pose_files.h"
#include "lookup/database/reference_database.h"
#include "lookup/localize/fix_store.h"
#include "lookup/localize/localize_app.h"
#include "lookup/localize/pose_stream.h"
#include "vehicle_fixture.h"

using namespace lookup;
using namespace lookup::vehicle_test;

namespace {

/// A database and a 20-frame query of ceiling frames with coarse poses from a file (0.5 m off).
struct CoarseFileRun {
    fs::path dir;
    localize::LocalizeRequest req;

    explicit CoarseFileRun(const std::string& name, QuerySpec q = {})
        : dir(lookup::test::freshDir("lookup_vehicle_" + name)) {
        const Scene scene;
        writeDatabase(scene, (dir / "db").string());
        writeQuery(scene, dir / "query.rawlog", q);
        common::PoseTrack coarse;
        // Margins beyond the query's frames, unless its clock jumps (they would overlap).
        const int margin = q.jump_at >= 0 ? 0 : 5;
        for (int k = q.first - margin; k < q.first + q.count + margin; ++k) {
            const double t = q.stamp(k) + q.period_s / 10;
            coarse.push_back({t, queryPose(k) + mrpt::poses::CPose3D(0.5, -0.2, 0, 0, 0, 0)});
        }
        std::sort(coarse.begin(), coarse.end(),
                  [](const auto& a, const auto& b) { return a.time_s < b.time_s; });
        common::writeTumPoseFile((dir / "coarse.tum").string(), coarse);
        req.db_dir = (dir / "db").string();
        req.rawlog = (dir / "query.rawlog").string();
        req.out_dir = (dir / "run").string();
        req.coarse_poses = (dir / "coarse.tum").string();
        req.sampling = "grid";
        req.progress = false;
    }

    localize::LiveRequest live() const {
        std::ofstream(dir / "sensors.ini")
            << "[CAM]\ndriver = CCameraSensor\nprocess_rate = 50\n"
            << "grabber_type = rawlog\nrawlog_file = " << (dir / "query.rawlog").string()
            << "\nrawlog_camera_sensor_label = CEILING_CAM\nsensorLabel = CEILING_CAM\n"
            << "pose_z = 1.5\n";  // the synthetic mount (CCameraSensor sets it)
        localize::LiveRequest l;
        l.base = req;
        l.sensors_ini = (dir / "sensors.ini").string();
        l.duration_s = 30;
        return l;
    }
};

nlohmann::json readTiming(const std::string& run) {
    std::ifstream in(fs::path(run) / "timing.json");
    return nlohmann::json::parse(in);
}

std::vector<nlohmann::json> ofType(const std::vector<nlohmann::json>& all, const char* type) {
    std::vector<nlohmann::json> out;
    for (const auto& m : all) {
        if (m.at("type") == type) out.push_back(m);
    }
    return out;
}

}  // namespace

TEST(PoseStream, LiveRunPublishesEveryFrameOverTcpAsInFramesCsvAndReportsTheStoppedCamera) {
    CoarseFileRun run("tcp");
    auto live = run.live();
    const int port = freePort();
    live.base.publish = "tcp://127.0.0.1:" + std::to_string(port);
    live.base.publish_wait_s = 20;  // the client below connects before the first frame
    live.quiet_timeout_s = 2.5;     // the camera's end is reported before the run stops
    auto client = std::async(std::launch::async, [port] {
        const int fd = connectLoopback(port);
        return fd < 0 ? std::vector<nlohmann::json>{} : readJsonLines(fd);
    });
    const auto timing = localize::runLiveLocalization(live);
    const auto messages = client.get();
    const auto rows = readFramesCsv(live.base.out_dir);
    ASSERT_EQ(timing.frames, 20u);
    ASSERT_EQ(rows.size(), 20u);

    const auto poses = ofType(messages, "pose");
    ASSERT_EQ(poses.size(), rows.size());
    double last_sent = 0;
    int refined = 0;
    for (std::size_t k = 0; k < poses.size(); ++k) {
        const auto& m = poses[k];
        for (const char* key : {"t_image", "t_sent", "x", "y", "yaw", "cov", "status", "reason",
                                "latency_ms", "frame"}) {
            EXPECT_TRUE(m.contains(key)) << key << " in frame " << k;
        }
        EXPECT_EQ(m.at("frame").get<std::size_t>(), k);
        EXPECT_GE(m.at("t_sent").get<double>(), last_sent);
        last_sent = m.at("t_sent").get<double>();
        EXPECT_GE(m.at("latency_ms").get<double>(), 0.0);
        EXPECT_LT(m.at("latency_ms").get<double>(), 1000.0);
        expectSameFrame(m, rows[k]);
        refined += m.at("status") == "refined";
    }
    EXPECT_GE(refined, 15);
    double latency_ms = 0, processing_ms = 0;
    for (const auto& m : poses) {
        latency_ms += m.at("latency_ms").get<double>() / double(poses.size());
        processing_ms += m.at("processing_ms").get<double>() / double(poses.size());
    }
    std::printf("pose latency on loopback: mean %.2f ms, of which processing %.2f ms\n", latency_ms,
                processing_ms);

    // Health: once a second, and at once when the camera stops (the rawlog's end).
    const auto health = ofType(messages, "health");
    ASSERT_GE(health.size(), 2u);
    const nlohmann::json* stopped = nullptr;
    for (const auto& h : health) {
        for (const char* key : {"frames_received", "frames_dropped", "last_fix_age_s", "status"}) {
            EXPECT_TRUE(h.contains(key)) << key;
        }
        if (!stopped && h.at("camera") == "stopped") stopped = &h;
    }
    ASSERT_NE(stopped, nullptr) << "the stopped camera was not reported";
    EXPECT_EQ((*stopped)["frames_received"]["CEILING_CAM"].get<int>(), 20);
    EXPECT_EQ((*stopped)["status"], rows.back().status);
    ASSERT_FALSE((*stopped)["events"].empty());
    EXPECT_NE((*stopped)["events"][0].get<std::string>().find("CEILING_CAM stopped"),
              std::string::npos);
    // Reported camera_timeout_s (1 s) after the last frame arrived, plus the polling.
    const auto& last = poses.back();
    const double arrival =
        last.at("t_sent").get<double>() - last.at("latency_ms").get<double>() / 1e3;
    const double delay = stopped->at("t_sent").get<double>() - arrival;
    EXPECT_GE(delay, 0.99);
    EXPECT_LT(delay, 1.1);
    std::printf("stopped camera reported %.3f s after its last frame arrived\n", delay);

    const auto t = readTiming(live.base.out_dir);
    EXPECT_EQ(t["publish"]["clients_connected"], 1);
    EXPECT_EQ(t["publish"]["dropped_queue_full"], 0);
    EXPECT_EQ(t["publish"]["sent"].get<std::size_t>(), messages.size());
    EXPECT_EQ(t["health"]["camera_stops"], 1);
}

TEST(PoseStream, ReplayPublishesEveryFrameOverUdp) {
    CoarseFileRun run("udp");
    const int port = freePort(SOCK_DGRAM);
    const int rx = socket(AF_INET, SOCK_DGRAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(bind(rx, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    run.req.publish = "udp://localhost:" + std::to_string(port);
    localize::runLocalization(run.req);

    std::vector<nlohmann::json> messages;
    char buf[65536];
    for (ssize_t n; (n = recv(rx, buf, sizeof buf, MSG_DONTWAIT)) > 0;) {
        messages.push_back(nlohmann::json::parse(std::string(buf, n)));
    }
    close(rx);
    const auto rows = readFramesCsv(run.req.out_dir);
    const auto poses = ofType(messages, "pose");
    ASSERT_EQ(rows.size(), 20u);
    ASSERT_EQ(poses.size(), rows.size());
    for (std::size_t k = 0; k < poses.size(); ++k) {
        EXPECT_EQ(poses[k].at("frame").get<std::size_t>(), k);
        expectSameFrame(poses[k], rows[k]);
    }
    // Health on the recorded clock: 2 s of frames, one message a second, and the last one.
    const auto health = ofType(messages, "health");
    ASSERT_EQ(health.size(), 2u);
    EXPECT_EQ(health.back().at("frames_received").at("CEILING_CAM"), 20);
    EXPECT_EQ(health.back().at("frames_processed"), 20);
}

TEST(PoseStream, NeverBlocksOnAClientThatDoesNotReadAndDropsOneThatLeaves) {
    localize::PoseStream stream("tcp://127.0.0.1:0", 64);
    const int idle = connectLoopback(stream.port());
    ASSERT_GE(idle, 0);
    ASSERT_TRUE(stream.waitForClient(5));
    // Far more than the socket buffers and the client's allowance hold.
    const std::string payload(8000, 'x');
    // A push that waited for the network would never return: the client never reads.
    const auto t0 = std::chrono::steady_clock::now();
    for (int k = 0; k < 5000; ++k) {
        stream.push({{"type", "pose"}, {"frame", k}, {"pad", payload}});
        if (k % 50 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    const double pushing_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    auto s = stream.stats();
    EXPECT_GT(s.dropped_slow_client + s.dropped_queue_full, 0u);
    EXPECT_EQ(s.queued + s.dropped_queue_full, 5000u);
    EXPECT_LT(pushing_s, 5.0);

    // The idle client leaves; a new one still gets what follows.
    close(idle);
    const int reader = connectLoopback(stream.port());
    ASSERT_GE(reader, 0);
    for (int wait = 0; wait < 100 && stream.stats().clients_disconnected == 0; ++wait) {
        stream.push({{"type", "pose"}, {"frame", -1}});
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    EXPECT_EQ(stream.stats().clients_disconnected, 1u);
    stream.push({{"type", "pose"}, {"frame", 9999}});
    stream.close();
    const auto got = readJsonLines(reader);
    ASSERT_FALSE(got.empty());
    EXPECT_EQ(got.back().at("frame"), 9999);
}

TEST(PoseStream, AnAddressThatCannotBeUsedIsAClearErrorBeforeAnyFrame) {
    CoarseFileRun run("bad_address");
    const int taken = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(bind(taken, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    ASSERT_EQ(listen(taken, 1), 0);
    socklen_t len = sizeof a;
    getsockname(taken, reinterpret_cast<sockaddr*>(&a), &len);
    const std::string in_use = "tcp://127.0.0.1:" + std::to_string(ntohs(a.sin_port));
    for (const auto& [url, why] : {std::pair<std::string, std::string>{in_use, "in use"},
                                   {"tcp://192.0.2.1:5000", "assign"},
                                   {"tcp://127.0.0.1:70000", "1-65535"},
                                   {"udp://127.0.0.1:0", "1-65535"},
                                   {"tcp://127.0.0.1", "HOST:PORT"},
                                   {"http://127.0.0.1:80", "udp://"}}) {
        run.req.publish = url;
        fs::remove_all(run.req.out_dir);
        try {
            localize::runLocalization(run.req);
            ADD_FAILURE() << url << " was accepted";
        } catch (const std::exception& e) {
            const std::string what = e.what();
            EXPECT_NE(what.find(url), std::string::npos) << what;
            EXPECT_NE(what.find(why), std::string::npos) << what;
        }
        EXPECT_FALSE(fs::exists(fs::path(run.req.out_dir) / "frames.csv")) << url;
    }
    close(taken);
}

namespace {

// The start-up scene: coarse stage from the forward views (SeqSLAM), so a run that starts
// without a fix needs start-up frames before it refines.
struct RestartScene {
    fs::path dir = lookup::test::freshDir("lookup_vehicle_restart");
    Scene scene;
    localize::LocalizeRequest req;
    RestartScene() {
        writeDatabase(scene, (dir / "db").string());
        // Before the power cycle: frames 0-15; after it (100 s later): from frame 15 on, where
        // the vehicle stopped.
        writeQuery(scene, dir / "before.rawlog", {0, 16});
        writeQuery(scene, dir / "after.rawlog", {15, 12, /*time_shift_s=*/100});
        req.db_dir = (dir / "db").string();
        req.sampling = "grid";
        req.progress = false;
    }
    std::vector<CsvFrame> run(const std::string& rawlog, const std::string& out,
                              const std::string& fix) {
        req.rawlog = (dir / rawlog).string();
        req.out_dir = (dir / out).string();
        req.persist_fix = fix;
        localize::runLocalization(req);
        return readFramesCsv(req.out_dir);
    }
};

}  // namespace

TEST(Restart, APersistedFixRefinesTheFirstFrameAndABadOneIsIgnored) {
    RestartScene s;
    const std::string fix = (s.dir / "fix.json").string();
    const auto before = s.run("before.rawlog", "before", fix);
    ASSERT_EQ(before.size(), 16u);
    ASSERT_EQ(before.back().status, "refined");
    EXPECT_NE(before.front().status, "refined");  // no fix at start: start-up frames first
    {
        std::ifstream in(fix);
        const auto j = nlohmann::json::parse(in);
        EXPECT_NEAR(j.at("x").get<double>(), before.back().x, 1e-5);
        EXPECT_NEAR(j.at("y").get<double>(), before.back().y, 1e-5);
        EXPECT_EQ(j.at("cov").size(), 9u);
        EXPECT_EQ(j.at("db").at("identity"),
                  localize::databaseIdentity(database::ReferenceDatabase::load(s.req.db_dir)));
    }
    EXPECT_FALSE(fs::exists(fix + ".tmp" + std::to_string(getpid())));

    // Restarted where it stopped: refined at its first frame, on the truth.
    const auto after = s.run("after.rawlog", "after", fix);
    ASSERT_EQ(after.size(), 12u);
    EXPECT_EQ(after[0].status, "refined");
    EXPECT_NEAR(after[0].x, queryPose(15).x(), 0.03);
    EXPECT_NEAR(after[0].y, queryPose(15).y(), 0.03);
    EXPECT_EQ(readTiming(s.req.out_dir)["persist_fix"]["offered"], true);

    // Without the fix the same frames need the start-up acquisition first.
    const auto cold = s.run("after.rawlog", "cold", "");
    ASSERT_EQ(cold.size(), 12u);
    EXPECT_NE(cold[0].status, "refined");

    // A fix from elsewhere (the vehicle was moved while off): the ceiling does not confirm it;
    // the run starts as without it and every fix is on the truth, none at the old place.
    const std::string moved = (s.dir / "moved.json").string();
    {
        std::ifstream in(fix);
        auto j = nlohmann::json::parse(in);
        j["x"] = 5.0;
        std::ofstream(moved) << j.dump();
    }
    const auto elsewhere = s.run("after.rawlog", "moved", moved);
    ASSERT_EQ(elsewhere.size(), 12u);
    EXPECT_NE(elsewhere[0].status, "refined");
    EXPECT_EQ(elsewhere.back().status, "refined");
    for (std::size_t k = 0; k < elsewhere.size(); ++k) {
        if (elsewhere[k].status != "refined") continue;
        EXPECT_NEAR(elsewhere[k].x, queryPose(15 + int(k)).x(), 0.03) << "frame " << k;
    }

    // A corrupt file, one from another database, a missing one: logged, ignored, run as cold.
    const std::string corrupt = (s.dir / "corrupt.json").string();
    std::ofstream(corrupt) << "{\"format\": \"lookup-fix\", \"x\": 1.0, \"y\":";
    const std::string other = (s.dir / "other.json").string();
    {
        std::ifstream in(fix);
        auto j = nlohmann::json::parse(in);
        j["db"]["identity"] = "0123456789abcdef-65";
        std::ofstream(other) << j.dump();
    }
    for (const auto& [file, why] : {std::pair<std::string, std::string>{corrupt, "corrupt"},
                                    {other, "another database"},
                                    {(s.dir / "missing.json").string(), "no persisted fix"}}) {
        testing::internal::CaptureStderr();
        const auto rows = s.run("after.rawlog", "bad_fix", file);
        const std::string log = testing::internal::GetCapturedStderr();
        ASSERT_EQ(rows.size(), 12u) << file;
        EXPECT_EQ(rows[0].status, cold[0].status) << file;
        EXPECT_EQ(rows.back().status, "refined") << file;  // it still localises
        EXPECT_NE(log.find(file), std::string::npos) << log;
        EXPECT_NE(log.find(why), std::string::npos) << log;
        const auto t = readTiming(s.req.out_dir);
        EXPECT_EQ(t["persist_fix"]["offered"], false) << file;
        EXPECT_NE(t["persist_fix"]["not_offered_because"].get<std::string>().find(why),
                  std::string::npos);
    }
    // The corrupt file is replaced by this run's fix.
    std::string why_not;
    EXPECT_TRUE(localize::readFixFile(
        corrupt, localize::databaseIdentity(database::ReferenceDatabase::load(s.req.db_dir)),
        why_not))
        << why_not;
}

TEST(Health, AClockJumpingBackIsReportedAndTheRunGoesOn) {
    // From frame 10 on every stamp is 1.9 s earlier: frame 10 comes 1.9 s before frame 9.
    CoarseFileRun run("clock_jump", {0, 20, 0, false, /*jump_at=*/10, /*jump_s=*/2.0});
    const int port = freePort(SOCK_DGRAM);
    const int rx = socket(AF_INET, SOCK_DGRAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(bind(rx, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    run.req.publish = "udp://127.0.0.1:" + std::to_string(port);
    testing::internal::CaptureStderr();
    const auto timing = localize::runLocalization(run.req);
    const std::string log = testing::internal::GetCapturedStderr();
    // The frames stamped before the last one processed are skipped as the localiser's input
    // check refuses them (named and counted), not fed out of order; the run goes on.
    EXPECT_EQ(timing.frames, 10u);
    EXPECT_EQ(readFramesCsv(run.req.out_dir).size(), 10u);
    EXPECT_NE(log.find("CEILING_CAM clock jumped back 1.900 s"), std::string::npos) << log;
    EXPECT_NE(log.find("skipped (time_backwards)"), std::string::npos) << log;

    std::vector<std::string> events;
    char buf[65536];
    for (ssize_t n; (n = recv(rx, buf, sizeof buf, MSG_DONTWAIT)) > 0;) {
        const auto m = nlohmann::json::parse(std::string(buf, n));
        if (m.at("type") != "health") continue;
        for (const auto& e : m.at("events")) events.push_back(e.get<std::string>());
    }
    close(rx);
    EXPECT_TRUE(std::any_of(events.begin(), events.end(), [](const std::string& e) {
        return e.find("CEILING_CAM clock jumped back 1.900 s") != std::string::npos;
    }));
    const auto t = readTiming(run.req.out_dir);
    EXPECT_EQ(t["skipped"]["time_backwards"], 20);  // 10 ceiling and 10 forward images
    EXPECT_EQ(t["health"]["clock_jumps"]["CEILING_CAM"]["count"], 1);
    EXPECT_NEAR(t["health"]["clock_jumps"]["CEILING_CAM"]["largest_s"].get<double>(), 1.9, 1e-6);

    // In real time the replay clock steps back with it: the frames after the jump are not
    // waited for 1.9 s late; at most a slow first frame makes the next one late.
    run.req.realtime = 1;
    run.req.out_dir = (run.dir / "realtime").string();
    const auto rt = localize::runLocalization(run.req);
    EXPECT_EQ(rt.frames, 10u);
    EXPECT_LE(rt.frames_dropped, 2u);
    EXPECT_LT(rt.wall_s, 2.0 + 0.5);
}

TEST(Health, RealTimeUnderLoadDropsFramesInsteadOfLaggingAndSaysHowMany) {
    // 2000 frames/s recorded: faster than a frame is localised, on any machine.
    QuerySpec q;
    q.count = 100;
    q.period_s = 0.0005;
    const double max_latency_s = 0.01;
    CoarseFileRun run("realtime_load", q);
    std::ofstream(run.dir / "rt.ini")
        << "[localizer]\nmax_latency_s = " << max_latency_s << "\nhealth_interval_s = 0.02\n";
    run.req.ini_file = (run.dir / "rt.ini").string();
    run.req.realtime = 1;
    const int port = freePort(SOCK_DGRAM);
    const int rx = socket(AF_INET, SOCK_DGRAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(bind(rx, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    run.req.publish = "udp://127.0.0.1:" + std::to_string(port);
    const auto timing = localize::runLocalization(run.req);

    const auto rows = readFramesCsv(run.req.out_dir);
    ASSERT_EQ(rows.size(), 100u);
    const auto dropped = std::count_if(rows.begin(), rows.end(),
                                       [](const CsvFrame& r) { return r.status == "dropped"; });
    EXPECT_GT(dropped, 0);
    EXPECT_LT(dropped, 100);
    EXPECT_EQ(timing.frames_dropped, static_cast<std::size_t>(dropped));
    EXPECT_EQ(readTiming(run.req.out_dir)["frames_dropped"], dropped);
    // Not lagging: the run ends about when the recording does, and every processed frame
    // started within max_latency_s of its arrival.
    double longest_frame_s = 0;
    std::size_t last_health_dropped = 0;
    char buf[65536];
    for (ssize_t n; (n = recv(rx, buf, sizeof buf, MSG_DONTWAIT)) > 0;) {
        const auto m = nlohmann::json::parse(std::string(buf, n));
        if (m.at("type") == "health") {
            last_health_dropped = m.at("frames_dropped").get<std::size_t>();
            continue;
        }
        if (m.at("status") == "dropped") continue;
        const double processing_ms = m.at("processing_ms").get<double>();
        longest_frame_s = std::max(longest_frame_s, processing_ms / 1e3);
        EXPECT_LT(m.at("latency_ms").get<double>() - processing_ms, 1e3 * max_latency_s + 30.0)
            << "frame " << m.at("frame");
    }
    close(rx);
    EXPECT_LT(timing.wall_s, q.count * q.period_s + max_latency_s + longest_frame_s + 0.1);
    EXPECT_EQ(last_health_dropped, timing.frames_dropped);  // the last health message says so
}

TEST(PoseStream, AClientThatLeavesOrNeverReadsDoesNotStopTheRun) {
    CoarseFileRun run("clients");
    const int port = freePort();
    run.req.publish = "tcp://127.0.0.1:" + std::to_string(port);
    run.req.publish_wait_s = 20;
    run.req.realtime = 1;  // 2 s: the clients come and go while frames are sent
    auto clients = std::async(std::launch::async, [port] {
        const int idle = connectLoopback(port);  // connects and never reads
        const int leaver = connectLoopback(port);
        char buf[256];
        const ssize_t got = recv(leaver, buf, sizeof buf, 0);  // the first message, then away
        close(leaver);
        std::this_thread::sleep_for(std::chrono::seconds(3));
        close(idle);
        return got;
    });
    testing::internal::CaptureStderr();
    const auto timing = localize::runLocalization(run.req);
    const std::string log = testing::internal::GetCapturedStderr();
    EXPECT_GT(clients.get(), 0);
    EXPECT_EQ(timing.frames, 20u);
    EXPECT_EQ(readFramesCsv(run.req.out_dir).size(), 20u);
    EXPECT_NE(log.find("disconnected"), std::string::npos) << log;
    const auto t = readTiming(run.req.out_dir);
    EXPECT_EQ(t["publish"]["clients_connected"], 2);
    EXPECT_GE(t["publish"]["clients_disconnected"], 1);
}
