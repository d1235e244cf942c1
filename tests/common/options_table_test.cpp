#include <gtest/gtest.h>
#include <mrpt/config/CConfigFileMemory.h>

#include "lookup/common/options_table.h"

using lookup::common::ConfigError;
using lookup::common::EnumNames;
using lookup::common::NamedConfigFile;
using lookup::common::OptionsTable;

namespace {

enum class Shape { Round, Square };
const EnumNames<Shape> kShapes = {{"round", Shape::Round}, {"square", Shape::Square}};

struct Sample {
    double ratio = 0.5;
    int count = 3;
    std::uint64_t seed = 7;
    bool on = false;
    std::string label = "cam";
    Shape shape = Shape::Round;
    double gap_m = 1.0;
};

OptionsTable keys(Sample& s) {
    OptionsTable t;
    t.add("ratio", s.ratio, 0.0, 1.0);
    t.add("count", s.count, 1, 10);
    t.add("seed", s.seed);
    t.add("on", s.on);
    t.add("label", s.label);
    t.add("shape", s.shape, kShapes);
    t.add("gap_m", s.gap_m, lookup::common::kPositive);
    return t;
}

std::string loadError(const std::string& text) {
    const NamedConfigFile file(text, "opts.ini");
    Sample s;
    try {
        keys(s).load(file, "sample");
    } catch (const ConfigError& e) {
        return e.what();
    }
    return "";
}

}  // namespace

TEST(OptionsTable, SaveThenLoadGivesTheSameValues) {
    Sample a;
    a.ratio = 1.0 / 3.0;  // needs 17 digits to read back exactly
    a.count = 9;
    a.seed = 18446744073709551615ull;
    a.on = true;
    a.label = "ceiling";
    a.shape = Shape::Square;
    mrpt::config::CConfigFileMemory mem;
    keys(a).save(mem, "sample");
    Sample b;
    keys(b).load(mem, "sample");
    EXPECT_EQ(b.ratio, a.ratio);
    EXPECT_EQ(b.count, a.count);
    EXPECT_EQ(b.seed, a.seed);
    EXPECT_EQ(b.on, a.on);
    EXPECT_EQ(b.label, a.label);
    EXPECT_EQ(b.shape, a.shape);
}

TEST(OptionsTable, AbsentKeysKeepTheirValues) {
    Sample s;
    keys(s).load(NamedConfigFile("[sample]\ncount = 4\n", "opts.ini"), "sample");
    EXPECT_EQ(s.count, 4);
    EXPECT_EQ(s.ratio, 0.5);
    EXPECT_EQ(s.shape, Shape::Round);
}

TEST(OptionsTable, UnknownKeyNamesFileSectionAndKey) {
    EXPECT_EQ(loadError("[sample]\ncuont = 4\n"), "opts.ini [sample] cuont: unknown key");
}

TEST(OptionsTable, RangeErrorNamesTheRange) {
    EXPECT_EQ(loadError("[sample]\ncount = 11\n"),
              "opts.ini [sample] count: 11 is out of range [1, 10]");
    EXPECT_EQ(loadError("[sample]\nratio = 1.5\n"),
              "opts.ini [sample] ratio: 1.5 is out of range [0, 1]");
    EXPECT_EQ(loadError("[sample]\ngap_m = 0\n"),
              "opts.ini [sample] gap_m: 0 is out of range (0, inf)");
    EXPECT_EQ(loadError("[sample]\nseed = -1\n"),
              "opts.ini [sample] seed: '-1' is not a non-negative integer");
}

TEST(OptionsTable, EnumErrorListsTheAllowedNames) {
    EXPECT_EQ(loadError("[sample]\nshape = oval\n"),
              "opts.ini [sample] shape: 'oval' is not one of round, square");
}

TEST(OptionsTable, MalformedValuesAreRefused) {
    EXPECT_NE(loadError("[sample]\non = maybe\n").find("opts.ini [sample] on: "),
              std::string::npos);
    EXPECT_NE(loadError("[sample]\ncount = 2x\n").find("not an integer"), std::string::npos);
}

TEST(OptionsTable, UnknownSectionNamesFileSectionAndKnownOnes) {
    const NamedConfigFile file("[sample]\ncount = 4\n[refine.matchr]\npatch_px = 4\n", "app.ini");
    try {
        lookup::common::rejectUnknownSections(file, {"sample", "refine.matcher"});
        FAIL() << "expected ConfigError";
    } catch (const ConfigError& e) {
        EXPECT_STREQ(e.what(),
                     "app.ini [refine.matchr]: unknown section (known: sample, refine.matcher)");
    }
    EXPECT_NO_THROW(lookup::common::rejectUnknownSections(file, {"sample", "refine.*"}));
}

TEST(OptionsTable, LoadAndCheckNamesTheFileForAFailedCheck) {
    struct Checked {
        int n = 1;
        void loadFromConfigFile(const mrpt::config::CConfigFileBase& src, const std::string& s) {
            OptionsTable t;
            t.add("n", n);
            t.load(src, s);
        }
        void check() const {
            if (n < 0) throw ConfigError("checked.n must be >= 0");
        }
    } c;
    try {
        lookup::common::loadAndCheck(c, NamedConfigFile("[checked]\nn = -2\n", "c.ini"), "checked");
        FAIL() << "expected ConfigError";
    } catch (const ConfigError& e) {
        EXPECT_STREQ(e.what(), "c.ini [checked]: checked.n must be >= 0");
    }
}

TEST(OptionsTable, CheckRangesNamesTheKeyAndItsRange) {
    Sample s;
    s.count = 0;
    s.ratio = 2.0;
    s.gap_m = -1.0;
    lookup::common::OptionsCheck c("sample");
    keys(s).checkRanges(c);
    EXPECT_EQ(c.message(),
              "sample.ratio must be in [0, 1]\nsample.count must be in [1, 10]\nsample.gap_m must "
              "be in (0, inf)");
    Sample fine;
    lookup::common::OptionsCheck ok("sample");
    keys(fine).checkRanges(ok);
    EXPECT_TRUE(ok.ok());
}
