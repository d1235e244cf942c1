#include "lookup/coarse/coarse_tool.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "lookup/coarse/options.h"
#include "lookup/test/support.h"
#include "route_rawlog.h"

namespace fs = std::filesystem;

namespace lookup::coarse {
namespace {

using testing::SyntheticRoute;

struct Fixture {
    fs::path dir;
    std::string ref, query, ref_gt, query_gt;
};

Fixture writeFixture(const std::string& name) {
    Fixture f;
    f.dir = lookup::test::freshDir("lookup_coarse_tool_" + name);
    SyntheticRoute route(120, 3, 21);
    f.ref = fs::absolute(f.dir / "ref.rawlog").string();
    f.query = fs::absolute(f.dir / "query.rawlog").string();
    f.ref_gt = f.ref + ".GT.txt";
    f.query_gt = f.query + ".GT.txt";
    testing::writeRouteRawlog(f.ref, route, testing::positionsFrom(0, 1, 120), 0.0, "FORWARD_CAM",
                              3.0, f.ref_gt);
    testing::writeRouteRawlog(f.query, route, testing::positionsFrom(20.2, 1.0, 60), 1000.0,
                              "FORWARD_CAM", 8.0, f.query_gt);
    return f;
}

std::vector<std::vector<std::string>> readCsv(const std::string& path) {
    std::vector<std::vector<std::string>> rows;
    std::ifstream in(path);
    std::string line;
    while (std::getline(in, line)) {
        std::vector<std::string> cells;
        std::stringstream ss(line);
        std::string cell;
        while (std::getline(ss, cell, ',')) cells.push_back(cell);
        rows.push_back(cells);
    }
    return rows;
}

TEST(CoarseTool, MatchesTwoRawlogsWithoutPoses) {
    const auto f = writeFixture("plain");
    const std::string csv = (f.dir / "matches.csv").string();
    const std::string png = (f.dir / "confusion.png").string();
    CoarseTool tool;
    ASSERT_TRUE(tool.initialize({"lookup-coarse", "--ref", f.ref, "--query", f.query, "--out", csv,
                                 "--quiet", "--confusion-png", png}));
    std::ostringstream out, err;
    ASSERT_EQ(tool.run(out, err), 0) << err.str();
    EXPECT_TRUE(fs::exists(png));
    const auto rows = readCsv(csv);
    ASSERT_EQ(rows.size(), 61u);
    EXPECT_EQ(rows[0][0], "query_index");
    EXPECT_EQ(rows[0][2], "reference_index");
    EXPECT_EQ(rows[0][5], "status");
    int correct = 0, full = 0;
    const std::size_t ds = CoarseOptions().sequence_length;
    for (std::size_t t = ds + 1; t < rows.size(); ++t) {  // rows[t] is query t-1: full buffer
        ++full;
        const double x = 20.2 + 1.0 * (t - 1);
        const auto& r = rows[t];
        if ((r[5] == "tracking" || r[5] == "global") && !r[2].empty() &&
            std::abs(std::stol(r[2]) - std::lround(x)) <= 1) {
            ++correct;
            EXPECT_NEAR(std::stod(r[3]), std::lround(x), 1.0);  // reference time = index here
        }
    }
    EXPECT_GE(correct, full - 1);
    EXPECT_EQ(tool.summary().frames, 60u);
}

TEST(CoarseTool, EvaluatesWithPosesAndSavesDescriptors) {
    const auto f = writeFixture("posed");
    const std::string csv = (f.dir / "m.csv").string();
    const std::string desc = (f.dir / "ref.coarse").string();
    CoarseTool tool;
    ASSERT_TRUE(tool.initialize({"lookup-coarse", "--ref", f.ref, "--query", f.query, "--out", csv,
                                 "--quiet", "--ref-poses", f.ref_gt, "--query-poses", f.query_gt,
                                 "--save-descriptors", desc}));
    std::ostringstream out, err;
    ASSERT_EQ(tool.run(out, err), 0) << err.str();
    EXPECT_EQ(tool.summary().evaluated, 60u);
    EXPECT_LT(tool.summary().share_over_10m, 0.55);  // only the first, short sequences miss
    EXPECT_NE(out.str().find("coarse error"), std::string::npos);
    EXPECT_EQ(readCsv(csv)[0][6], "error_m");

    // Same run from the saved descriptors gives the same matches.
    const std::string csv2 = (f.dir / "m2.csv").string();
    CoarseTool again;
    ASSERT_TRUE(again.initialize({"lookup-coarse", "--ref-descriptors", desc, "--query", f.query,
                                  "--out", csv2, "--quiet"}));
    ASSERT_EQ(again.run(out, err), 0) << err.str();
    const auto a = readCsv(csv), b = readCsv(csv2);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t i = 1; i < a.size(); ++i) EXPECT_EQ(a[i][2], b[i][2]) << "row " << i;
}

TEST(CoarseTool, BadInputIsReportedNotCrashed) {
    const auto f = writeFixture("bad");
    const std::string csv = (f.dir / "m.csv").string();
    {  // absent camera label: exit 2 (bad input data), message lists the labels present
        CoarseTool tool;
        ASSERT_TRUE(tool.initialize({"lookup-coarse", "--ref", f.ref, "--query", f.query, "--out",
                                     csv, "--quiet", "--camera", "LEFT_CAM"}));
        std::ostringstream out, err;
        EXPECT_EQ(tool.run(out, err), 2);
        EXPECT_NE(err.str().find("LEFT_CAM"), std::string::npos) << err.str();
        EXPECT_NE(err.str().find("FORWARD_CAM"), std::string::npos) << err.str();
    }
    {  // a reference shorter than the sequence length
        const std::string ini = (f.dir / "long.ini").string();
        std::ofstream(ini) << "[coarse]\nsequence_length = 200\n";
        CoarseTool tool;
        ASSERT_TRUE(tool.initialize({"lookup-coarse", "--ref", f.ref, "--query", f.query, "--out",
                                     csv, "--quiet", "--ini", ini}));
        std::ostringstream out, err;
        EXPECT_EQ(tool.run(out, err), 1);
        EXPECT_NE(err.str().find("sequence_length"), std::string::npos) << err.str();
    }
    {  // a missing rawlog and a bad ini key
        const std::string ini = (f.dir / "typo.ini").string();
        std::ofstream(ini) << "[coarse]\nthumb_widht_px = 32\n";
        CoarseTool tool;
        ASSERT_TRUE(tool.initialize({"lookup-coarse", "--ref", f.ref, "--query", f.query, "--out",
                                     csv, "--quiet", "--ini", ini}));
        std::ostringstream out, err;
        EXPECT_EQ(tool.run(out, err), 1);
        EXPECT_NE(err.str().find("thumb_widht_px"), std::string::npos) << err.str();
        CoarseTool missing;
        ASSERT_TRUE(missing.initialize({"lookup-coarse", "--ref", "/nonexistent/r.rawlog",
                                        "--query", f.query, "--out", csv, "--quiet"}));
        EXPECT_EQ(missing.run(out, err), 2);
        EXPECT_NE(err.str().find("/nonexistent/r.rawlog"), std::string::npos);
    }
    {  // an output that cannot be written: exit 3, naming it, on one line
        CoarseTool tool;
        ASSERT_TRUE(tool.initialize({"lookup-coarse", "--ref", f.ref, "--query", f.query, "--out",
                                     "/nonexistent/m.csv", "--quiet"}));
        std::ostringstream out, err;
        EXPECT_EQ(tool.run(out, err), 3);
        const std::string text = err.str();
        EXPECT_NE(text.find("/nonexistent/m.csv.tmp: write error"), std::string::npos) << text;
        EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 1) << text;
    }
    {  // both or neither reference inputs
        CoarseTool tool;
        EXPECT_FALSE(tool.initialize({"lookup-coarse", "--query", f.query, "--out", csv}));
        EXPECT_EQ(tool.exitCode(), 1);
    }
}

}  // namespace
}  // namespace lookup::coarse
