#include "lookup/coarse/coarse_localizer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "synthetic_route.h"

namespace lookup::coarse {
namespace {

using testing::SyntheticRoute;

CoarseOptions testOptions() {
    CoarseOptions o;  // defaults: 64x48 thumbnails (identity resize on the 64x48 test images)
    return o;
}

/// One reference per tile at positions 0, 1, 2, ... with their true pose (x = position).
std::shared_ptr<ReferenceDescriptors> makeReferences(SyntheticRoute& route, int count,
                                                     const CoarseOptions& o,
                                                     bool with_poses = false) {
    auto refs = std::make_shared<ReferenceDescriptors>(o);
    refs->setImageSize(SyntheticRoute::kW, SyntheticRoute::kH);
    for (int i = 0; i < count; ++i) {
        std::optional<mrpt::poses::CPose3D> pose;
        if (with_poses) pose = mrpt::poses::CPose3D(i, 0, 0, 0, 0, 0);
        refs->add(i, computeDescriptor(route.image(i, 4.0), o), pose);
    }
    return refs;
}

struct RunStats {
    int full = 0;            ///< frames with a full buffer
    int seq_correct = 0;     ///< sequence match within 1 place of the truth
    int single_correct = 0;  ///< single-frame best match within 1 place
    std::size_t max_tracking_evaluated = 0;
    std::size_t max_tracking_candidates = 0;
    int tracking = 0;
};

/// Query traverse starting at `x0`, `speed` tiles per frame, darker and noisier than the
/// references; compares every full-buffer result with the truth and with single-frame matching.
RunStats runQuery(SyntheticRoute& route, CoarseLocalizer& loc, double x0, double speed, int frames,
                  bool odometry = false) {
    RunStats s;
    const auto& refs = loc.references();
    for (int t = 0; t < frames; ++t) {
        const double x = x0 + speed * t;
        const auto image = route.image(x, 8.0, 0.7, 25.0);
        const auto r = loc.process(image, 1000.0 + t,
                                   odometry && t > 0 ? std::optional<double>(speed) : std::nullopt);
        if (t < loc.options().sequence_length - 1) {
            EXPECT_EQ(r.status, CoarseStatus::NotEnoughFrames) << "frame " << t;
            continue;
        }
        ++s.full;
        const long truth = std::lround(x);
        if (r.hasMatch() && std::abs(static_cast<long>(r.reference_index) - truth) <= 1 &&
            r.usable()) {
            ++s.seq_correct;
        }
        const auto d = computeDescriptor(image, loc.options());
        std::size_t best = 0;
        float best_d = 1e9f;
        for (std::size_t i = 0; i < refs.size(); ++i) {
            const float v = descriptorDifference(d, refs.descriptor(i));
            if (v < best_d) best_d = v, best = i;
        }
        if (std::abs(static_cast<long>(best) - truth) <= 1) ++s.single_correct;
        if (r.status == CoarseStatus::Tracking) {
            ++s.tracking;
            s.max_tracking_evaluated = std::max(s.max_tracking_evaluated, r.evaluated_references);
            s.max_tracking_candidates = std::max(s.max_tracking_candidates, r.searched_candidates);
        }
    }
    return s;
}

TEST(CoarseLocalizer, SequenceBeatsSingleFrameUnderAliasing) {
    SyntheticRoute route(300, 3, 7);  // 3 tile types: every frame has ~100 look-alikes
    const auto o = testOptions();
    CoarseLocalizer loc(makeReferences(route, 300, o), o);
    const auto s = runQuery(route, loc, 40.3, 1.0, 120);
    ASSERT_EQ(s.full, 120 - o.sequence_length + 1);
    EXPECT_GE(s.seq_correct, 0.95 * s.full);
    EXPECT_LE(s.single_correct, 0.30 * s.full);  // single frames alias
    EXPECT_GT(s.tracking, s.full / 2);
}

TEST(CoarseLocalizer, MatchesAtTwiceAndHalfTheReferenceSpeed) {
    SyntheticRoute route(400, 3, 11);
    const auto o = testOptions();
    auto refs = makeReferences(route, 400, o);
    {
        CoarseLocalizer loc(refs, o);
        const auto s = runQuery(route, loc, 10.0, 2.0, 90);
        EXPECT_GE(s.seq_correct, 0.95 * s.full) << "2x speed";
    }
    {
        CoarseLocalizer loc(refs, o);
        const auto s = runQuery(route, loc, 200.0, 0.5, 90);
        EXPECT_GE(s.seq_correct, 0.90 * s.full) << "0.5x speed";
    }
}

TEST(CoarseLocalizer, TrackingWorkDoesNotGrowWithTheDatabase) {
    const auto o = testOptions();
    std::size_t evaluated[2], candidates[2];
    const int sizes[2] = {200, 2000};
    for (int k = 0; k < 2; ++k) {
        SyntheticRoute route(sizes[k], 3, 5);
        CoarseLocalizer loc(makeReferences(route, sizes[k], o), o);
        const auto s = runQuery(route, loc, 60.0, 1.0, 80);
        ASSERT_GT(s.tracking, 40) << "database of " << sizes[k];
        EXPECT_GE(s.seq_correct, 0.95 * s.full);
        evaluated[k] = s.max_tracking_evaluated;
        candidates[k] = s.max_tracking_candidates;
    }
    // Candidates: the tracking window only. Evaluations: a few new entries per buffered column.
    EXPECT_LE(candidates[1], static_cast<std::size_t>(2 * o.tracking_half_window_refs + 1));
    EXPECT_EQ(candidates[0], candidates[1]);
    EXPECT_LE(evaluated[1], evaluated[0] + 5);
    EXPECT_LT(evaluated[1], 200u);  // far fewer than the 2000 references
}

TEST(CoarseLocalizer, IndexedGlobalSearchFindsThePlaceAtACostThatDoesNotGrowWithTheDatabase) {
    // Global searches (start-up, and after a kidnapping) through the descriptor index score a
    // few windows; the exhaustive search scores every reference.
    CoarseOptions indexed = testOptions();
    indexed.global_index_min_references = 0;
    CoarseOptions exhaustive = testOptions();
    exhaustive.global_index_min_references = 1 << 30;
    const int sizes[2] = {1500, 15000};
    std::size_t global_candidates[2] = {0, 0}, global_evaluated[2] = {0, 0};
    for (int k = 0; k < 2; ++k) {
        SyntheticRoute route(sizes[k], 400, 17);  // 4 to 40 look-alikes per place
        auto refs = makeReferences(route, sizes[k], indexed);
        for (const bool use_index : {false, true}) {
            if (!use_index && k == 1) continue;  // (the exhaustive one only as the reference)
            CoarseLocalizer loc(refs, use_index ? indexed : exhaustive);
            ASSERT_EQ(loc.indexed(), use_index);
            int correct = 0, full = 0;
            for (int leg = 0; leg < 2; ++leg) {  // the second leg is a kidnapping
                const double x0 = leg == 0 ? 0.31 * sizes[k] : 0.77 * sizes[k];
                for (int t = 0; t < 70; ++t) {
                    const double x = x0 + t;
                    const auto r = loc.process(route.image(x, 8.0, 0.7, 25.0), 1000.0 * leg + t);
                    const bool global = r.status != CoarseStatus::Tracking;
                    if (use_index && global) {
                        global_candidates[k] =
                            std::max(global_candidates[k], r.searched_candidates);
                        global_evaluated[k] = std::max(global_evaluated[k], r.evaluated_references);
                    }
                    if (t < 2 * indexed.sequence_length) continue;  // the old place may still win
                    ++full;
                    correct += r.usable() &&
                               std::abs(static_cast<long>(r.reference_index) - std::lround(x)) <= 1;
                }
            }
            EXPECT_GE(correct, 0.95 * full) << sizes[k] << " references, index " << use_index;
        }
    }
    // Windows around the places the index finds: far fewer candidates than references, and
    // about as many on a 10x longer reference.
    EXPECT_GT(global_candidates[0], 0u);
    EXPECT_LT(global_candidates[1], static_cast<std::size_t>(sizes[1] / 5));
    EXPECT_LT(global_candidates[1], 3 * global_candidates[0]);
    EXPECT_LT(global_evaluated[1], 2 * global_evaluated[0]) << global_evaluated[0];
}

TEST(CoarseLocalizer, UnconfidentIndexedSearchesFallBackToTheWholeReference) {
    // 3 textures: any single thumbnail matches a third of the places, so the index proposes
    // look-alikes; every global_index_full_search_every unconfident frames one search scores
    // the whole reference, which finds the place.
    SyntheticRoute route(10000, 3, 9);  // without the safety net: right only at frame 93
    CoarseOptions o = testOptions();
    o.global_index_min_references = 0;
    o.global_index_full_search_every = 40;
    CoarseLocalizer loc(makeReferences(route, 10000, o), o);
    int whole = 0, since_whole = 0, first_right = -1;
    for (int t = 0; t < 150; ++t) {
        const double x = 1234.4 + t;
        const auto r = loc.process(route.image(x, 8.0, 0.7, 25.0), t);
        const bool right =
            r.usable() && std::abs(static_cast<long>(r.reference_index) - std::lround(x)) <= 1;
        if (right && first_right < 0) first_right = t;
        if (r.searched_candidates >= 10000) {
            ++whole;
            EXPECT_GE(since_whole, o.global_index_full_search_every) << "frame " << t;
            since_whole = 0;
        } else {
            ++since_whole;
            if (r.status != CoarseStatus::Tracking) {
                EXPECT_LT(r.searched_candidates, 1500u) << "frame " << t;
            }
        }
        if (r.usable() && t > first_right + 2 && first_right >= 0) {
            EXPECT_TRUE(right) << "frame " << t;
        }
    }
    EXPECT_GE(whole, 1);
    ASSERT_GE(first_right, 0);
    EXPECT_LE(first_right, o.sequence_length + o.global_index_full_search_every + 5);
}

TEST(CoarseLocalizer, RecoversFromKidnapping) {
    SyntheticRoute route(400, 3, 3);
    const auto o = testOptions();
    CoarseLocalizer loc(makeReferences(route, 400, o), o);
    // Track from 30 for 40 frames, then jump to 250.
    for (int t = 0; t < 40; ++t) loc.process(route.image(30.0 + t, 8.0), t);
    int recovered_after = -1;
    for (int t = 0; t < 60; ++t) {
        const double x = 250.0 + t;
        const auto r = loc.process(route.image(x, 8.0), 40.0 + t);
        const bool right =
            r.usable() && std::abs(static_cast<long>(r.reference_index) - std::lround(x)) <= 1;
        if (right && recovered_after < 0) recovered_after = t;
        if (recovered_after >= 0 && t > recovered_after + 2) {
            EXPECT_TRUE(right) << "lost again at frame " << t << " after the jump";
        }
        // Until the buffer holds mostly post-jump frames the old trajectory may still win
        // (inherent to sequence matching); after that a confident wrong answer must not happen.
        if (t >= o.sequence_length && r.usable() && !right) {
            ADD_FAILURE() << "confident wrong match at frame " << t << ": " << r.reference_index
                          << " vs " << x;
        }
    }
    ASSERT_GE(recovered_after, 0);
    EXPECT_LE(recovered_after, o.sequence_length + 5);
}

TEST(CoarseLocalizer, OdometryWidensTheSpeedRangeWhenReferencesArePosed) {
    // 3.5 tiles per frame is outside [V_min, V_max] = [0.4, 2.5]: only odometry finds it.
    SyntheticRoute route(600, 3, 13);
    const auto o = testOptions();
    auto refs = makeReferences(route, 600, o, /*with_poses=*/true);
    CoarseLocalizer with(refs, o);
    const auto a = runQuery(route, with, 20.0, 3.5, 90, /*odometry=*/true);
    // With odometry the first global match waits one sequence for its confirmation.
    EXPECT_GE(a.seq_correct, 0.95 * (a.full - o.sequence_length));
    CoarseLocalizer without(refs, o);
    const auto b = runQuery(route, without, 20.0, 3.5, 60, /*odometry=*/false);
    EXPECT_LT(b.seq_correct, 0.5 * b.full);
}

TEST(CoarseLocalizer, OdometryHoldsTheTrackThroughAUniformStretch) {
    // 300 places, 100..179 all alike: no sequence can place a frame in there.
    SyntheticRoute route(300, 3, 17);
    route.makeUniform(100, 179, 0);
    const auto o = testOptions();
    auto refs = makeReferences(route, 300, o, /*with_poses=*/true);
    struct Inside {
        int frames = 0, usable = 0, right = 0, held = 0, confident_wrong = 0;
    };
    auto drive = [&](const CoarseOptions& opt) {
        CoarseLocalizer loc(refs, opt);
        Inside in;
        for (int t = 0; t < 180; ++t) {
            const double x = 20.0 + t;  // 1 place (1 m) per frame
            const auto r = loc.process(route.image(x, 8.0, 0.7, 25.0), 1000.0 + t,
                                       t > 0 ? std::optional<double>(1.0) : std::nullopt);
            const bool right = r.hasMatch() &&
                               std::abs(static_cast<long>(r.reference_index) - std::lround(x)) <= 2;
            if (r.usable() && !right && r.status != CoarseStatus::Odometry) ++in.confident_wrong;
            if (x < 110 || x > 179) continue;  // inside, a few places past its start
            ++in.frames;
            in.usable += r.usable();
            in.right += r.usable() && right;
            in.held += r.status == CoarseStatus::Odometry;
        }
        return in;
    };
    const Inside held = drive(o);
    EXPECT_GE(held.right, 0.95 * held.frames);
    EXPECT_GE(held.held, held.frames / 2) << "the window cannot decide inside: odometry does";
    EXPECT_EQ(held.confident_wrong, 0);

    CoarseOptions no_coast = o;
    no_coast.max_coast_m = 0;  // the track ends where the window match turns unconfident
    const Inside dropped = drive(no_coast);
    EXPECT_LT(dropped.right, 0.5 * dropped.frames);
    EXPECT_EQ(dropped.held, 0);
}

TEST(CoarseLocalizer, HeldTrackIsDroppedAndTheRightPlaceFoundAfterKidnappingWithOdometry) {
    SyntheticRoute route(400, 3, 3);
    const auto o = testOptions();
    CoarseLocalizer loc(makeReferences(route, 400, o, /*with_poses=*/true), o);
    for (int t = 0; t < 70; ++t) {
        loc.process(route.image(30.0 + t, 8.0), t,
                    t > 0 ? std::optional<double>(1.0) : std::nullopt);
    }
    // Carried to 250 while odometry says one more metre: the held track is now wrong.
    int recovered_after = -1;
    for (int t = 0; t < 120; ++t) {
        const double x = 250.0 + t;
        const auto r = loc.process(route.image(x, 8.0), 70.0 + t, 1.0);
        const bool right =
            r.usable() && std::abs(static_cast<long>(r.reference_index) - std::lround(x)) <= 1;
        if (right && recovered_after < 0) recovered_after = t;
        if (recovered_after >= 0) {
            EXPECT_TRUE(right) << "lost again at frame " << t << " after the jump";
        } else if (r.usable() && t >= o.sequence_length) {
            // Until the buffer holds mostly post-jump frames the old trajectory may still win
            // (as without odometry); after that the old place is only held, never claimed.
            EXPECT_EQ(r.status, CoarseStatus::Odometry) << "frame " << t << ": " << r.reason;
        }
    }
    // The held track is dropped once a sequence of unconfident windows says many places fit
    // better; the global search over the long odometry sequence then needs mostly post-jump
    // frames, and its match one more sequence to be confirmed.
    ASSERT_GE(recovered_after, 0);
    EXPECT_LE(recovered_after, 4 * o.sequence_length);

    // Without audits (the caller verifies the place itself, CoarseQuery::audit = false) the
    // held track survives the same frames: only the caller, or max_coast_m, ends it.
    CoarseLocalizer unaudited(makeReferences(route, 400, o, /*with_poses=*/true), o);
    for (int t = 0; t < 70; ++t) {
        unaudited.process(route.image(30.0 + t, 8.0), t,
                          t > 0 ? std::optional<double>(1.0) : std::nullopt, true, false);
    }
    for (int t = 0; t <= recovered_after; ++t) {
        const auto r = unaudited.process(route.image(250.0 + t, 8.0), 70.0 + t, 1.0, true, false);
        if (t >= o.sequence_length) {
            EXPECT_EQ(r.status, CoarseStatus::Odometry) << "frame " << t << ": " << r.reason;
        }
    }
}

TEST(CoarseLocalizer, RejectedMatchStartsAFreshConfirmedAcquisition) {
    SyntheticRoute route(300, 3, 21);
    const auto o = testOptions();
    CoarseLocalizer loc(makeReferences(route, 300, o, /*with_poses=*/true), o);
    auto frame = [&](int t) {
        return loc.process(route.image(20.0 + t, 8.0), t,
                           t > 0 ? std::optional<double>(1.0) : std::nullopt);
    };
    int t = 0;
    for (; t < 80; ++t) frame(t);
    ASSERT_EQ(frame(t++).status, CoarseStatus::Tracking);
    // The consumer found no ceiling match around it: the stage searches the whole reference
    // again, and trusts the result only once a later sequence agrees.
    loc.rejectLastMatch();
    const auto first = frame(t++);
    EXPECT_EQ(first.status, CoarseStatus::Unconfirmed) << first.reason;
    EXPECT_FALSE(first.usable());
    int confirmed_after = -1;
    for (int k = 1; k <= o.sequence_length + 1 && confirmed_after < 0; ++k, ++t) {
        const auto r = frame(t);
        if (r.status == CoarseStatus::Global) {
            confirmed_after = k;
            EXPECT_NEAR(static_cast<double>(r.reference_index), 20.0 + t, 1.0);
        }
    }
    EXPECT_EQ(confirmed_after, o.sequence_length);
}

TEST(CoarseLocalizer, AStoppedAndReversingVehicleKeepsItsTrackByTheOdometrysSign) {
    // Forward from place 30 to 100, 15 frames stopped there, back to 40, forward again; the
    // forward camera meanwhile sees the survey's views at the places it passes.
    SyntheticRoute route(400, 3, 29);
    const auto o = testOptions();
    auto refs = makeReferences(route, 400, o, /*with_poses=*/true);
    std::vector<double> path{30.0};
    for (int k = 0; k < 70; ++k) path.push_back(path.back() + 1.0);
    for (int k = 0; k < 15; ++k) path.push_back(path.back());
    for (int k = 0; k < 60; ++k) path.push_back(path.back() - 1.0);
    for (int k = 0; k < 40; ++k) path.push_back(path.back() + 1.0);
    struct Phase {
        int frames = 0, right = 0, wrong = 0;
    };
    // `sign`: the odometry's travel as given to the stage (signed, or its size alone).
    auto drive = [&](bool sign, const CoarseOptions& opt) {
        CoarseLocalizer loc(refs, opt);
        EXPECT_EQ(loc.indexed(), opt.global_index_min_references <= 400);
        Phase stopped, reversing, after;
        for (std::size_t t = 0; t < path.size(); ++t) {
            std::optional<double> step;
            if (t > 0) step = sign ? path[t] - path[t - 1] : std::abs(path[t] - path[t - 1]);
            const auto r = loc.process(route.image(path[t], 8.0, 0.7, 25.0), 1000.0 + t, step);
            Phase* phase = t > 70 && t <= 85    ? &stopped
                           : t > 85 && t <= 145 ? &reversing
                           : t > 145            ? &after
                                                : nullptr;
            if (phase == nullptr) continue;
            ++phase->frames;
            const bool right =
                std::abs(static_cast<long>(r.reference_index) - std::lround(path[t])) <= 1;
            phase->right += r.usable() && right;
            phase->wrong += r.usable() && !right;
        }
        return std::array<Phase, 3>{stopped, reversing, after};
    };
    // Global searches scored whole (a short reference) and through the descriptor index.
    CoarseOptions indexed = o;
    indexed.global_index_min_references = 100;
    for (const CoarseOptions& opt : {o, indexed}) {
        for (const Phase& p : drive(true, opt)) {
            EXPECT_GE(p.right, 0.9 * p.frames);
            EXPECT_EQ(p.wrong, 0);
        }
    }
    // With the distance's size alone the track runs on while the vehicle backs up: the
    // reversing frames are lost, or placed where the vehicle is not.
    const auto unsigned_travel = drive(false, o);
    EXPECT_LT(unsigned_travel[1].right, 0.5 * unsigned_travel[1].frames);
}

TEST(CoarseLocalizer, BadInputGivesReasonsNotCrashes) {
    SyntheticRoute route(50, 3, 1);
    const auto o = testOptions();
    // Empty and too-short references: a clear error at construction.
    EXPECT_THROW(CoarseLocalizer(std::make_shared<ReferenceDescriptors>(o), o),
                 std::invalid_argument);
    try {
        CoarseLocalizer(makeReferences(route, 5, o), o);
        ADD_FAILURE() << "5 references accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("sequence_length"), std::string::npos);
    }
    CoarseOptions other = o;
    other.thumb_width_px = 32;
    EXPECT_THROW(CoarseLocalizer(makeReferences(route, 50, o), other), std::invalid_argument);

    CoarseLocalizer loc(makeReferences(route, 50, o), o);
    // A single query frame: a best guess, flagged as not enough frames, with a reason.
    auto r = loc.process(route.image(3, 4.0), 0);
    EXPECT_EQ(r.status, CoarseStatus::NotEnoughFrames);
    EXPECT_FALSE(r.usable());
    EXPECT_NE(r.reason.find("sequence_length"), std::string::npos);
    // A query image of another size.
    cv::Mat big(96, 128, CV_8U, cv::Scalar(100));
    r = loc.process(mrpt::img::CImage(big, mrpt::img::DEEP_COPY), 1);
    EXPECT_EQ(r.status, CoarseStatus::InvalidInput);
    EXPECT_NE(r.reason.find("128x96"), std::string::npos);
    EXPECT_NE(r.reason.find("64x48"), std::string::npos);
    // An empty image and a missing one.
    r = loc.process(mrpt::img::CImage(), 2);
    EXPECT_EQ(r.status, CoarseStatus::InvalidInput);
    CoarseQuery q;
    q.time_s = 3;
    EXPECT_EQ(loc.locate(q).status, CoarseStatus::InvalidInput);
    // A descriptor of the wrong length.
    r = loc.processDescriptor(Descriptor(10, 128), 4);
    EXPECT_EQ(r.status, CoarseStatus::InvalidInput);
    // A featureless query stream (lens covered): never a confident match.
    cv::Mat flat(48, 64, CV_8U, cv::Scalar(90));
    for (int t = 0; t < 30; ++t) {
        r = loc.process(mrpt::img::CImage(flat, mrpt::img::DEEP_COPY), 10 + t);
        EXPECT_FALSE(r.usable()) << "frame " << t;
    }
}

}  // namespace
}  // namespace lookup::coarse
