// Training on the pipe fixture lowers the loss and learns to score the pipes (outliers) below
// the clean ceiling; the held-out best point beats a random point. Deterministic for a seed.

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "fixture.h"
#include "lookup/database/reference_database.h"
#include "lookup/fcn/trainer.h"

using namespace lookup;
using namespace lookup::fcn;

namespace {

struct Data {
    std::vector<TrainingSample> train, val;
    LabelSet labels;
};

Data makeData(const database::ReferenceDatabase& db, const TrainOptions& o,
              const std::string& rawlog) {
    Data d;
    d.labels = generateLabels(db, {rawlog}, {fixture::posesFile(rawlog)}, o.labels);
    const auto image_of = [&db](std::size_t i) { return db.ceilingImage(i).clone(); };
    d.train = samplesFromPairs(d.labels.pairs, false, image_of);
    d.val = samplesFromPairs(d.labels.pairs, true, image_of);
    return d;
}

}  // namespace

TEST(Trainer, LearnsToScorePipesBelowTheCeiling) {
    const auto dir = lookup::test::freshDir("lookup_fcn_trainer");
    std::vector<double> xs;
    for (double x = -4; x <= 4.01; x += 0.5) xs.push_back(x);
    fixture::writeDatabase((dir / "db").string(), xs);
    fixture::writeQuery((dir / "q.rawlog").string(), fixture::drive(-3.6, 3.6, 0.2, 0.15));
    const auto db = database::ReferenceDatabase::load((dir / "db").string());
    const TrainOptions o = fixture::smallOptions();
    const Data d = makeData(db, o, (dir / "q.rawlog").string());
    ASSERT_GE(d.train.size(), 8u);
    ASSERT_GE(d.val.size(), 2u);

    HeatMapModel model(o.network, o.training.seed);
    // Before training the pipes are not ranked low.
    const mrpt::poses::CPose3D probe(4.3, -0.1, 0, 0.1, 0, 0);  // a view not in the data
    const cv::Mat image = fixture::scene().render(probe);
    const cv::Mat mask = fixture::scene().pipeMask(probe);
    cv::Mat core_pipe, core_ceiling;  // away from the edges (the 20 px patches straddle them)
    cv::erode(mask, core_pipe, cv::Mat::ones(11, 11, CV_8U));
    cv::erode(255 - mask, core_ceiling, cv::Mat::ones(11, 11, CV_8U));
    ASSERT_GT(cv::countNonZero(core_pipe), 200);
    ASSERT_GT(cv::countNonZero(core_ceiling), 200);

    int steps_seen = 0;
    const TrainResult r =
        train(model, d.train, d.val, o.training, [&](int, int, int, double) { ++steps_seen; });
    std::printf("labels %.2f s, train %.2f s, %d steps, %zu samples %zu points\n",
                d.labels.stats.seconds, r.seconds, r.steps, d.train.size(), d.labels.stats.points);
    EXPECT_EQ(steps_seen, r.steps);
    ASSERT_EQ(int(r.epochs.size()), o.training.epochs);
    EXPECT_LT(r.epochs.back().train_loss, 0.8 * r.epochs.front().train_loss);
    EXPECT_LT(r.epochs.back().val_loss, 0.8 * r.initial_val_loss);

    const cv::Mat heat = model.predict(image);
    const double in_pipe = cv::mean(heat, core_pipe)[0];
    const double on_ceiling = cv::mean(heat, core_ceiling)[0];
    EXPECT_LT(in_pipe + 0.3, on_ceiling) << "pipe " << in_pipe << " ceiling " << on_ceiling;

    const auto image_of = [&db](std::size_t i) { return db.ceilingImage(i).clone(); };
    const PointEvaluation ev = evaluatePoints(model, d.labels.pairs, image_of);
    EXPECT_EQ(ev.pairs, d.labels.stats.held_out_pairs);
    EXPECT_GE(ev.best_point_inlier_share, 0.9);
    EXPECT_GT(ev.best_point_inlier_share, ev.random_point_inlier_share);
    EXPECT_GT(ev.top12_inlier_share, ev.random_point_inlier_share);
    EXPECT_GT(ev.heat_inlier_mean, ev.heat_outlier_mean);

    // Same seed, same data: the same model.
    HeatMapModel again(o.network, o.training.seed);
    TrainingOptions two = o.training;
    two.epochs = 2;
    HeatMapModel first(o.network, o.training.seed);
    train(first, d.train, d.val, two);
    train(again, d.train, d.val, two);
    EXPECT_EQ(cv::norm(first.predict(image), again.predict(image), cv::NORM_INF), 0.0);
}

TEST(Trainer, RefusesEmptyOrSingleClassData) {
    const TrainOptions o = fixture::smallOptions();
    HeatMapModel model(o.network);
    EXPECT_THROW(train(model, {}, {}, o.training), std::invalid_argument);
    TrainingSample s;
    s.image = cv::Mat(60, 80, CV_8UC1, cv::Scalar(100));
    s.points = {{10, 10}, {20, 20}};
    s.labels = {1, 1};
    try {
        train(model, {s}, {}, o.training);
        FAIL() << "single-class labels were accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("inlier"), std::string::npos) << e.what();
    }
}
