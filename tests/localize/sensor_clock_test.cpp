// The localiser's own sensors' time offsets ([time_offsets] of the --ini): read and checked,
// applied to the stamps where observations come in, in corrected time order, and visible in
// the run's frame times.

#include <gtest/gtest.h>
#include <mrpt/config/CConfigFile.h>
#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/obs/CObservationOdometry.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "localize_fixture.h"
#include "lookup/common/config.h"
#include "lookup/localize/fix_store.h"
#include "lookup/localize/sensor_clock.h"

namespace fs = std::filesystem;
using namespace lookup;
using namespace lookup::localize_testing;

namespace {

mrpt::obs::CObservation::Ptr odometryAt(double t) {
    auto o = mrpt::obs::CObservationOdometry::Create();
    o->sensorLabel = "ODOMETRY";
    o->timestamp = mrpt::Clock::fromDouble(t);
    return o;
}

double stampOf(const localize::SensorClock::Item& item) {
    return mrpt::Clock::toDouble(item.obs->timestamp);
}

std::vector<double> frameTimes(const fs::path& run) {
    std::ifstream in(run / "frames.csv");
    std::vector<double> t;
    std::string line;
    std::getline(in, line);  // header
    while (std::getline(in, line)) t.push_back(std::stod(line.substr(0, line.find(','))));
    return t;
}

}  // namespace

TEST(SensorClock, ReadsOffsetsPerLabelAndRefusesBadValuesNamingTheKey) {
    mrpt::config::CConfigFileMemory ini;
    ini.write("time_offsets", "CEILING_CAM", "-0.040");
    ini.write("time_offsets", "ODOMETRY", "0.01");
    const auto clock = localize::SensorClock::fromConfig(ini, "loc.ini");
    EXPECT_DOUBLE_EQ(clock.offsetOf("CEILING_CAM"), -0.040);
    EXPECT_DOUBLE_EQ(clock.offsetOf("ODOMETRY"), 0.01);
    EXPECT_DOUBLE_EQ(clock.offsetOf("FORWARD_CAM"), 0.0);
    for (const char* bad : {"abc", "0.04 s", "2", "nan"}) {
        mrpt::config::CConfigFileMemory wrong;
        wrong.write("time_offsets", "CEILING_CAM", bad);
        try {
            localize::SensorClock::fromConfig(wrong, "loc.ini");
            ADD_FAILURE() << bad << " accepted";
        } catch (const common::ConfigError& e) {
            EXPECT_NE(std::string(e.what()).find("loc.ini [time_offsets] CEILING_CAM"),
                      std::string::npos)
                << e.what();
        }
    }
    EXPECT_TRUE(localize::SensorClock::fromConfig(mrpt::config::CConfigFileMemory(), "x").empty());
}

TEST(SensorClock, ShiftsStampsAndReleasesInCorrectedOrder) {
    mrpt::config::CConfigFileMemory ini;
    ini.write("time_offsets", "CEILING_CAM", "-0.040");
    auto clock = localize::SensorClock::fromConfig(ini, "loc.ini");
    std::vector<double> out;
    const auto take = [&](std::vector<localize::SensorClock::Item> items) {
        for (const auto& i : items) out.push_back(stampOf(i));
    };
    take(clock.push({odometryAt(10.00), 0, 0}));
    auto image = mrpt::obs::CObservationImage::Create();
    image->sensorLabel = "CEILING_CAM";
    image->timestamp = mrpt::Clock::fromDouble(10.03);  // exposed at 9.99
    take(clock.push({image, 0, 1}));
    take(clock.push({odometryAt(10.02), 0, 2}));
    take(clock.flush());
    ASSERT_EQ(out.size(), 3u);
    EXPECT_NEAR(out[0], 9.99, 1e-6);
    EXPECT_NEAR(out[1], 10.00, 1e-6);
    EXPECT_NEAR(out[2], 10.02, 1e-6);
}

TEST(SensorClock, AConfiguredCameraOffsetShiftsTheReportedFrameTimes) {
    // The query camera stamps 50 ms after its exposure; odometry is on time.
    const auto dir = lookup::test::freshDir("lookup_localize_sensor_clock");
    auto req = planarRun(dir, [](int, mrpt::obs::CObservationImage& img, auto&) {
        img.timestamp = mrpt::Clock::fromDouble(mrpt::Clock::toDouble(img.timestamp) + 0.05);
    });
    req.out_dir = (dir / "late").string();
    localize::runLocalization(req);
    const auto late = frameTimes(req.out_dir);
    std::ofstream((dir / "loc.ini").string()) << "[time_offsets]\nCEILING_CAM = -0.050\n";
    req.ini_file = (dir / "loc.ini").string();
    req.out_dir = (dir / "shifted").string();
    localize::runLocalization(req);
    const auto shifted = frameTimes(req.out_dir);
    ASSERT_EQ(late.size(), 20u);
    ASSERT_EQ(shifted.size(), late.size());
    for (std::size_t i = 0; i < late.size(); ++i) {
        EXPECT_NEAR(late[i], kT0 + 0.1 * i + 0.05, 1e-5);
        EXPECT_NEAR(shifted[i], kT0 + 0.1 * i, 1e-5);  // the exposure time: the pose's time
    }
    std::ifstream run_ini(dir / "shifted" / "run.ini");
    const std::string text((std::istreambuf_iterator<char>(run_ini)), {});
    EXPECT_NE(text.find("[time_offsets]"), std::string::npos);
    EXPECT_NE(text.find("CEILING_CAM"), std::string::npos);
}

TEST(SensorClock, AConfiguredCameraOffsetIsCheckedNotReplacedByTheEstimate) {
    // On a database whose survey clock is known, the camera's estimated offset is applied by
    // default; a vehicle whose camera offset is configured keeps its measurement.
    const auto dir = lookup::test::freshDir("lookup_localize_clock_auto");
    PlanarDrive drive;
    drive.survey_camera.time_offset_sigma_s = 0.004;
    auto req = planarRun(
        dir, [](int, mrpt::obs::CObservationImage&, auto&) {}, 20, drive);
    const auto applyMode = [&](const std::string& ini_text, const std::string& run) {
        std::ofstream((dir / (run + ".ini")).string()) << ini_text;
        req.ini_file = (dir / (run + ".ini")).string();
        req.out_dir = (dir / run).string();
        localize::runLocalization(req);
        mrpt::config::CConfigFile used((dir / run / "run.ini").string());
        return used.read_string("localizer", "apply_camera_time_offset", "");
    };
    EXPECT_EQ(applyMode("[localizer]\nreferences_per_query = 3\n", "estimated"), "auto");
    EXPECT_EQ(applyMode("[time_offsets]\nCEILING_CAM = -0.010\n", "configured"), "never");
    EXPECT_EQ(applyMode("[time_offsets]\nODOMETRY = -0.020\n", "odometry_only"), "auto");
}

TEST(SensorClock, TheCameraClockIsCarriedFromRunToRunAgainstAKnownSurveyClock) {
    // A straight drive estimates nothing of its own: the offset an earlier weave measured,
    // carried in the vehicle's file, is applied from its first frame, and the file is kept for
    // the next run. Against a database whose survey clock is unknown the file is left alone.
    const auto dir = lookup::test::freshDir("lookup_localize_clock_carried");
    PlanarDrive drive;
    drive.survey_camera.time_offset_sigma_s = 0.004;
    auto req = planarRun(
        dir, [](int, mrpt::obs::CObservationImage&, auto&) {}, 20, drive);
    const std::string file = (dir / "clock.json").string();
    localize::writeCameraClockFile(file, {"CEILING_CAM", {-0.030, 0.002, 300}, 0.0});
    req.camera_clock = file;
    req.out_dir = (dir / "carried").string();
    localize::runLocalization(req);
    const auto times = frameTimes(req.out_dir);
    ASSERT_EQ(times.size(), 20u);
    for (std::size_t i = 0; i < times.size(); ++i) {
        EXPECT_NEAR(times[i], kT0 + 0.1 * i - 0.030, 1e-5) << "frame " << i;
    }
    std::ifstream timing(dir / "carried" / "timing.json");
    const auto offset = nlohmann::json::parse(timing).at("camera_time_offset");
    EXPECT_DOUBLE_EQ(offset.at("applied_s").get<double>(), -0.030);
    EXPECT_DOUBLE_EQ(offset.at("carried_s").get<double>(), -0.030);
    EXPECT_EQ(offset.at("written").get<double>(), 1.0);
    std::string why_not;
    const auto kept = localize::readCameraClockFile(file, "CEILING_CAM", why_not);
    ASSERT_TRUE(kept) << why_not;
    EXPECT_DOUBLE_EQ(kept->estimate.offset_s, -0.030);
    EXPECT_EQ(kept->estimate.pairs, 300u);
    EXPECT_GT(kept->saved_unix_s, 0.0);

    // Another camera's file, a corrupt one: said naming the file, the run starts afresh.
    const auto startsAfresh = [&](const std::string& bad, const std::string& why) {
        req.camera_clock = bad;
        req.out_dir = (dir / "afresh").string();
        testing::internal::CaptureStderr();
        localize::runLocalization(req);
        const std::string log = testing::internal::GetCapturedStderr();
        EXPECT_NE(log.find(bad + ": " + why), std::string::npos) << log;
        EXPECT_NEAR(frameTimes(req.out_dir).front(), kT0, 1e-5) << bad;
    };
    const std::string other = (dir / "other.json").string();
    localize::writeCameraClockFile(other, {"FRONT_CEILING", {-0.030, 0.002, 300}, 0.0});
    startsAfresh(other, "the offset of camera 'FRONT_CEILING'");
    const std::string corrupt = (dir / "corrupt.json").string();
    std::ofstream(corrupt) << "{\"format\": \"lookup-camera-clock\", \"offset_s\": ";
    startsAfresh(corrupt, "corrupt");

    const auto unknown = lookup::test::freshDir("lookup_localize_clock_not_carried");
    auto plain = planarRun(unknown, [](int, mrpt::obs::CObservationImage&, auto&) {});
    plain.camera_clock = file;
    testing::internal::CaptureStderr();
    localize::runLocalization(plain);
    const std::string log = testing::internal::GetCapturedStderr();
    EXPECT_NE(log.find(file + ": not carried"), std::string::npos) << log;
    EXPECT_NEAR(frameTimes(plain.out_dir).front(), kT0, 1e-5);
    const auto untouched = localize::readCameraClockFile(file, "CEILING_CAM", why_not);
    ASSERT_TRUE(untouched) << why_not;
    EXPECT_DOUBLE_EQ(untouched->saved_unix_s, kept->saved_unix_s);
}
