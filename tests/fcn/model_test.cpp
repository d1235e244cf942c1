// The network: output of the image's size in [0, 1], save/load round trip, and refusal of a
// model file of another architecture, a truncated or a foreign file, naming the file.

#include <gtest/gtest.h>

#include <fstream>

#include "fixture.h"
#include "lookup/fcn/model.h"

using namespace lookup;
using namespace lookup::fcn;
namespace fs = std::filesystem;

namespace {
NetworkOptions small() { return fixture::smallOptions().network; }

void expectRefusedNaming(const std::string& path, const NetworkOptions* expected,
                         const std::string& reason) {
    try {
        HeatMapModel::load(path, expected);
        FAIL() << path << " was accepted";
    } catch (const ModelError& e) {
        EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find(reason), std::string::npos) << e.what();
    }
}
}  // namespace

TEST(Model, OutputHasTheImageSizeAndIsAProbability) {
    const HeatMapModel model(small());
    EXPECT_GT(model.parameterCount(), 1000u);
    for (const cv::Size size : {cv::Size(160, 120), cv::Size(97, 61)}) {  // odd sizes too
        cv::Mat image(size, CV_8UC1);
        cv::randu(image, 0, 255);
        const cv::Mat heat = model.predict(image);
        ASSERT_EQ(heat.size(), size);
        ASSERT_EQ(heat.type(), CV_32FC1);
        EXPECT_TRUE(cv::checkRange(heat, true, nullptr, 0.0, 1.0));
    }
}

TEST(Model, SaveLoadRoundTripGivesIdenticalOutputs) {
    const auto dir = lookup::test::freshDir("lookup_fcn_model");
    const HeatMapModel model(small(), 3);
    const cv::Mat image = fixture::scene().render(mrpt::poses::CPose3D(0.3, 0, 0, 0, 0, 0));
    const std::string path = (dir / "m.pt").string();
    model.save(path);
    EXPECT_FALSE(fs::exists(path + ".tmp"));
    const NetworkOptions expected = small();
    const HeatMapModel loaded = HeatMapModel::load(path, &expected);
    EXPECT_TRUE(loaded.options() == small());
    EXPECT_EQ(cv::norm(model.predict(image), loaded.predict(image), cv::NORM_INF), 0.0);
    // A different seed gives different weights (the comparison above can fail).
    EXPECT_GT(cv::norm(model.predict(image), HeatMapModel(small(), 4).predict(image), cv::NORM_INF),
              0.0);
}

TEST(Model, AnotherArchitectureATruncatedOrForeignFileIsRefusedNamingTheFile) {
    const auto dir = lookup::test::freshDir("lookup_fcn_model_bad");
    const std::string path = (dir / "m.pt").string();
    HeatMapModel(small()).save(path);

    NetworkOptions wider = small();
    wider.base_channels = 16;
    expectRefusedNaming(path, &wider, "another architecture");

    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    const std::string truncated = (dir / "truncated.pt").string();
    std::ofstream(truncated, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
    expectRefusedNaming(truncated, nullptr, "corrupt or truncated");

    const std::string text = (dir / "text.pt").string();
    std::ofstream(text) << "not a model\n";
    expectRefusedNaming(text, nullptr, "corrupt or truncated");

    expectRefusedNaming((dir / "missing.pt").string(), nullptr, "no such model file");
}
