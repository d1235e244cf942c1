#include "lookup/survey/pose_audit.h"

#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/math/TPoint2D.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <optional>

#include "ceiling_frames.h"
#include "lookup/refine/refiner.h"

namespace lookup::survey {
namespace {

using detail::PosedCeilingFrame;

/// Another traverse's fixes nearer each other than this are one place, not rivals [m].
constexpr double kSamePlace_m = 0.3;
/// A rival fix explaining the image with this share of the best's inliers or more makes the
/// comparison inconclusive (a repeating ceiling).
constexpr double kRivalShare = 0.8;
/// Frames of the other traverse refined against per hint: the nearest cameras.
constexpr std::size_t kReferencesPerHint = 3;

struct AuditedTraverse {
    const CeilingTraverse* t = nullptr;
    std::vector<PosedCeilingFrame> frames;
    std::vector<mrpt::math::TPoint2D> cameras;  ///< each frame's camera position in the map
    /// The same positions, searched by MRPT's KD-tree.
    std::unique_ptr<mrpt::maps::CSimplePointsMap> camera_index;
};

AuditedTraverse audited(const CeilingTraverse& t) {
    AuditedTraverse a{
        &t, detail::posedCeilingFrames(t), {}, std::make_unique<mrpt::maps::CSimplePointsMap>()};
    for (const auto& f : a.frames) {
        const auto camera = f.pose + (*t.ceiling)[f.index]->cameraPose;
        a.cameras.emplace_back(camera.x(), camera.y());
        a.camera_index->insertPoint(float(camera.x()), float(camera.y()), 0.0f);
    }
    return a;
}

double timeOf(const AuditedTraverse& a, std::size_t k) {
    return mrpt::Clock::toDouble((*a.t->ceiling)[a.frames[k].index]->timestamp);
}

/// The frames of `b` whose cameras stood nearest `p`, within `max_m`.
std::vector<std::size_t> nearestCameras(const AuditedTraverse& b, const mrpt::math::TPoint2D& p,
                                        double max_m) {
    std::vector<std::size_t> found, out;
    std::vector<float> dist_sq;
    if (b.cameras.empty()) return out;
    b.camera_index->kdTreeNClosestPoint2DIdx(float(p.x), float(p.y), kReferencesPerHint, found,
                                             dist_sq);
    for (std::size_t i = 0; i < found.size(); ++i) {
        if (dist_sq[i] <= max_m * max_m) out.push_back(found[i]);
    }
    return out;
}

struct Fix {
    mrpt::poses::CPose2D pose;
    double inlier_share = 0;
    double other_time_s = 0;  ///< image time of the other traverse's nearest frame used
};

/// Rectified, prepared images, each loaded from disk once per audit step.
class Images {
  public:
    Images(const std::optional<refine::Rectifier>& rectifier, const refine::Refiner& refiner)
        : rectifier_(rectifier), refiner_(refiner) {}

    mrpt::obs::CObservationImage query(const AuditedTraverse& a, std::size_t k) const {
        auto& obs = *(*a.t->ceiling)[a.frames[k].index];
        auto out = rectifier_ ? rectifier_->rectify(obs) : obs;
        obs.image.unload();
        return out;
    }

    const refine::ReferenceImage& reference(const AuditedTraverse& b, std::size_t k) {
        const auto key = std::make_pair(b.t, k);
        auto it = cache_.find(key);
        if (it != cache_.end()) return it->second;
        auto ref =
            refine::ReferenceImage::fromObservation(std::int64_t(k), query(b, k), b.frames[k].pose);
        ref.prepare(refiner_.options().matcher);
        return cache_.emplace(key, std::move(ref)).first->second;
    }

    /// The cache holds the other traverse's frames near one sample only.
    void clear() { cache_.clear(); }

  private:
    const std::optional<refine::Rectifier>& rectifier_;
    const refine::Refiner& refiner_;
    std::map<std::pair<const CeilingTraverse*, std::size_t>, refine::ReferenceImage> cache_;
};

/// Sample `j` of `a` refined against `b`'s frames nearest the camera it would have at `hint`.
std::optional<Fix> refineAt(const AuditedTraverse& a, std::size_t j, const AuditedTraverse& b,
                            const mrpt::poses::CPose3D& hint, double ceiling_height_m,
                            double view_m, const mrpt::obs::CObservationImage& query,
                            const refine::Refiner& refiner, Images& images) {
    const auto camera = hint + (*a.t->ceiling)[a.frames[j].index]->cameraPose;
    const auto near = nearestCameras(b, {camera.x(), camera.y()}, view_m);
    if (near.empty()) return std::nullopt;
    std::vector<refine::ReferenceImage> refs;
    for (std::size_t k : near) refs.push_back(images.reference(b, k));
    refine::CoarseHint coarse;
    coarse.vehicle_pose = hint;
    coarse.ceiling_height_m = ceiling_height_m;
    const auto r = refiner.refine(query, coarse, refs);
    if (!r.accepted()) return std::nullopt;
    return Fix{mrpt::poses::CPose2D(r.pose.mean), r.inlier_share, timeOf(b, near.front())};
}

enum class Verdict { NotCompared, Agreed, Disagreed, Inconclusive };

struct Comparison {
    Verdict verdict = Verdict::NotCompared;
    double distance_m = 0;  ///< |fix - laser pose|
    Fix fix;                ///< when agreed or disagreed
};

double distance(const Fix& f, const mrpt::poses::CPose3D& p) {
    return std::hypot(f.pose.x() - p.x(), f.pose.y() - p.y());
}

/// How one frame is compared with another traverse.
struct Search {
    double ceiling_height_m = 0;
    double shift_step_m = 0;  ///< between hints shifted along the heading [m]
    double reach_m = 0;       ///< the farthest shift [m]
};

/// Sample `j` of `a`, at vehicle pose `laser`, against traverse `b`: at that pose, else shifted
/// along its heading.
Comparison compare(const AuditedTraverse& a, std::size_t j, const mrpt::poses::CPose3D& laser,
                   const AuditedTraverse& b, const Search& search, const SurveyOptions& o,
                   const refine::Refiner& refiner, Images& images) {
    const double view_m = o.pose_audit_view_distance_m;
    const double ceiling_height_m = search.ceiling_height_m;
    const auto camera = laser + (*a.t->ceiling)[a.frames[j].index]->cameraPose;
    if (nearestCameras(b, {camera.x(), camera.y()}, view_m).empty()) return {};
    Comparison c{Verdict::Inconclusive, 0, {}};
    const auto query = images.query(a, j);
    std::vector<Fix> fixes;
    if (auto f = refineAt(a, j, b, laser, ceiling_height_m, view_m, query, refiner, images)) {
        fixes.push_back(*f);
    } else {
        for (double s = search.shift_step_m; s <= search.reach_m + 1e-9; s += search.shift_step_m) {
            for (double sign : {-1.0, 1.0}) {
                const auto hint = laser + mrpt::poses::CPose3D(sign * s, 0, 0, 0, 0, 0);
                if (auto f =
                        refineAt(a, j, b, hint, ceiling_height_m, view_m, query, refiner, images)) {
                    fixes.push_back(*f);
                }
            }
        }
    }
    images.clear();
    if (fixes.empty()) return c;
    const auto best = *std::max_element(fixes.begin(), fixes.end(), [](const Fix& x, const Fix& y) {
        return x.inlier_share < y.inlier_share;
    });
    for (const auto& f : fixes) {
        const double apart = std::hypot(f.pose.x() - best.pose.x(), f.pose.y() - best.pose.y());
        if (apart > kSamePlace_m && f.inlier_share >= kRivalShare * best.inlier_share) return c;
    }
    c.distance_m = distance(best, laser);
    c.fix = best;
    c.verdict =
        c.distance_m <= o.pose_audit_max_disagreement_m ? Verdict::Agreed : Verdict::Disagreed;
    return c;
}

/// The shift between hints: the matcher's reach around one hint (half its search window at the
/// ceiling's distance), so consecutive hints leave no gap.
double shiftStep(const std::optional<refine::Rectifier>& rectifier, const refine::Refiner& refiner,
                 double camera_to_ceiling_m) {
    if (!rectifier || !(camera_to_ceiling_m > 0)) return 0.5;
    const double metres_per_px = camera_to_ceiling_m / rectifier->target().fx();
    return 0.5 * refiner.options().matcher.search_range_px * metres_per_px;
}

refine::RefinerOptions auditRefinerOptions(double ceiling_height_m) {
    // The localiser's guard against repeating texture: a point whose second-best match is
    // within 20 % of the best is not used (share/lookup/localize-mine-*.ini).
    refine::RefinerOptions ro;
    ro.matcher.min_distinctiveness = 0.2;
    ro.estimator.ceiling_height_m = ceiling_height_m;
    return ro;
}

/// What frames are compared with: the localiser's refiner, the stored references' camera and
/// the shift between hints at the ceiling's distance.
struct Matching {
    Matching(const std::vector<CeilingTraverse>& traverses, double ceiling_height_m,
             const SurveyOptions& o)
        : refiner(auditRefinerOptions(ceiling_height_m)),
          rectifier(detail::storedCameraRectifier(traverses, o)) {
        double camera_z = 0;
        for (const auto& t : traverses) {
            if (!t.ceiling->empty()) camera_z = t.ceiling->front()->cameraPose.z();
        }
        shift_step_m = shiftStep(rectifier, refiner, ceiling_height_m - camera_z);
    }
    const refine::Refiner refiner;
    const std::optional<refine::Rectifier> rectifier;
    double shift_step_m = 0.5;
};

double quantile(std::vector<double> v, double q) {
    if (v.empty()) return 0;
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, std::size_t(q * double(v.size())))];
}

// Whether an image can be read at all (an external file may be missing): comparisons of an
// unreadable one say nothing about where the traverse is. An external image is unloaded again.
bool readable(mrpt::obs::CObservationImage& obs) {
    bool ok = false;
    try {
        ok = obs.image.getWidth() > 0;
    } catch (const std::exception&) {
    }
    obs.image.unload();
    return ok;
}

/// The frames of `a` every `spacing_m` of travel up to `up_to_m`.
std::vector<std::size_t> sampleFrames(const AuditedTraverse& a, double up_to_m, double spacing_m) {
    std::vector<std::size_t> samples;
    if (a.frames.empty()) return samples;
    for (double s = 0; s <= up_to_m; s += spacing_m) {
        const std::size_t j = detail::nearestTravel(a.frames, s);
        if (samples.empty() || samples.back() != j) samples.push_back(j);
    }
    return samples;
}

/// One traverse's samples: audited against every other, suspects into `out`. Returns how many
/// of its comparisons were made on readable images and how many agreed.
std::pair<std::size_t, std::size_t> auditTraverse(const std::vector<AuditedTraverse>& all,
                                                  std::size_t ai, const Search& search,
                                                  const SurveyOptions& o,
                                                  const refine::Refiner& refiner, Images& images,
                                                  std::vector<double>& agreed_m, PoseAudit& out) {
    const auto& a = all[ai];
    const std::size_t compared_before = out.compared, agreed_before = out.agreed;
    std::size_t unreadable = 0;
    if (a.frames.empty()) return {0, 0};
    const auto samples = sampleFrames(a, a.frames.back().travel_m, o.pose_audit_spacing_m);
    out.sampled += samples.size();
    for (std::size_t si = 0; si < samples.size(); ++si) {
        const std::size_t j = samples[si];
        const bool sample_readable = readable(*(*a.t->ceiling)[a.frames[j].index]);
        std::size_t agreed = 0;
        std::optional<std::pair<double, std::size_t>> worst;  ///< disagreement, against
        for (std::size_t bi = 0; bi < all.size(); ++bi) {
            if (bi == ai) continue;
            Comparison c;
            bool threw = false;
            try {
                c = compare(a, j, a.frames[j].pose, all[bi], search, o, refiner, images);
            } catch (const std::exception&) {
                images.clear();  // an unreadable image: nothing to compare with
                c.verdict = Verdict::Inconclusive;
                threw = true;
            }
            if (c.verdict == Verdict::NotCompared) continue;
            ++out.compared;
            unreadable += threw || !sample_readable ? 1 : 0;
            if (c.verdict == Verdict::Inconclusive) ++out.inconclusive;
            if (c.verdict == Verdict::Agreed || c.verdict == Verdict::Disagreed) {
                const auto& laser = a.frames[j].pose;
                out.fixes.push_back({a.t->name, all[bi].t->name, timeOf(a, j), c.fix.other_time_s,
                                     c.fix.pose.x() - laser.x(), c.fix.pose.y() - laser.y()});
            }
            if (c.verdict == Verdict::Agreed) {
                ++out.agreed;
                ++agreed;
                agreed_m.push_back(c.distance_m);
            }
            if (c.verdict == Verdict::Disagreed) {
                ++out.disagreed;
                if (!worst || c.distance_m > worst->first) worst = {c.distance_m, bi};
            }
        }
        if (agreed > 0 || !worst) continue;
        ++out.suspect;
        SuspectStretch s;
        s.traverse = a.t->name;
        s.sample_s = timeOf(a, j);
        s.from_s = si > 0 ? timeOf(a, samples[si - 1]) : -1e300;
        s.to_s = si + 1 < samples.size() ? timeOf(a, samples[si + 1]) : 1e300;
        s.disagreement_m = worst->first;
        s.against = all[worst->second].t->name;
        out.stretches.push_back(s);
    }
    return {out.compared - compared_before - unreadable, out.agreed - agreed_before};
}

// A traverse none of whose many comparisons found its ceiling where its poses put it, while the
// others' did, is placed wrong as a whole (a start aliased along a uniform drive): every
// reference of it is suspect.
constexpr std::size_t kMinComparedToDiscard = 10;

void discardWholeTraverse(const std::string& name, std::size_t compared, PoseAudit& out) {
    SuspectStretch s;
    s.traverse = name;
    s.from_s = -1e300;
    s.to_s = 1e300;
    s.whole_traverse_compared = compared;
    out.stretches.push_back(s);
    ++out.traverses_discarded;
}

/// The start a trial puts `a` at (its frames' poses relative to the trial's origin), corrected by
/// where `b`'s ceiling finds its first sampled frame with a fix: none when fewer than two find
/// one, or a later one implies a start farther than the odometry between them may slip.
std::optional<mrpt::poses::CPose2D> trialStart(const AuditedTraverse& a,
                                               const std::vector<std::size_t>& samples,
                                               const mrpt::poses::CPose2D& start,
                                               const AuditedTraverse& b, const Search& search,
                                               const SurveyOptions& o, const Matching& m,
                                               Images& images) {
    std::vector<std::pair<mrpt::poses::CPose2D, double>> implied;  // start, travel
    for (std::size_t k = 0; k < samples.size() && implied.size() + samples.size() - k >= 2; ++k) {
        const std::size_t j = samples[k];
        const mrpt::poses::CPose2D relative(a.frames[j].pose);
        const mrpt::poses::CPose3D hint(start + relative);
        Comparison c;
        try {
            c = compare(a, j, hint, b, search, o, m.refiner, images);
        } catch (const std::exception&) {
            images.clear();  // an unreadable image decides nothing
            continue;
        }
        if (c.verdict == Verdict::Agreed || c.verdict == Verdict::Disagreed) {
            implied.emplace_back(c.fix.pose + (-relative), a.frames[j].travel_m);
        }
    }
    if (implied.size() < 2) return std::nullopt;
    const auto& [first, first_travel_m] = implied.front();
    for (const auto& [p, travel_m] : implied) {
        const double slip_m = kOdometrySlipShare * (travel_m - first_travel_m);
        if (p.distanceTo(first) > o.pose_audit_max_disagreement_m + slip_m) return std::nullopt;
    }
    return first;
}

}  // namespace

std::vector<std::optional<mrpt::poses::CPose2D>> startsFromCeiling(
    const CeilingTraverse& traverse, const std::vector<mrpt::poses::CPose2D>& trial_starts,
    const CeilingTraverse& mapped, double ceiling_height_m, double travel_m, double reach_m,
    const SurveyOptions& o) {
    std::vector<std::optional<mrpt::poses::CPose2D>> out(trial_starts.size());
    const AuditedTraverse a = audited(traverse), b = audited(mapped);
    const auto samples = sampleFrames(a, travel_m, o.pose_audit_spacing_m);
    if (samples.empty() || b.frames.empty()) return out;
    const Matching m({traverse, mapped}, ceiling_height_m, o);
    const Search search{ceiling_height_m, m.shift_step_m, reach_m};
    Images images(m.rectifier, m.refiner);
    for (std::size_t k = 0; k < trial_starts.size(); ++k) {
        out[k] = trialStart(a, samples, trial_starts[k], b, search, o, m, images);
    }
    return out;
}

bool PoseAudit::excludes(const std::string& traverse, double time_s) const {
    return std::any_of(stretches.begin(), stretches.end(), [&](const SuspectStretch& s) {
        return s.traverse == traverse && time_s > s.from_s && time_s < s.to_s;
    });
}

PoseAudit auditLaserPoses(const std::vector<CeilingTraverse>& traverses, double ceiling_height_m,
                          const SurveyOptions& o) {
    const auto started = std::chrono::steady_clock::now();
    PoseAudit out;
    if (!o.pose_audit) {
        out.note = "off ([survey] pose_audit = false)";
        return out;
    }
    if (traverses.size() < 2) {
        out.note = "one reference traverse: no other one to check its poses against";
        return out;
    }
    out.ran = true;
    std::vector<AuditedTraverse> all;
    for (const auto& t : traverses) all.push_back(audited(t));
    const Matching m(traverses, ceiling_height_m, o);
    const Search search{ceiling_height_m, m.shift_step_m, o.pose_audit_search_m};
    Images images(m.rectifier, m.refiner);
    std::vector<double> agreed_m;
    std::vector<std::pair<std::size_t, std::size_t>> counts;  // compared, agreed per traverse
    for (std::size_t ai = 0; ai < all.size(); ++ai) {
        counts.push_back(auditTraverse(all, ai, search, o, m.refiner, images, agreed_m, out));
    }
    for (std::size_t ai = 0; ai < all.size(); ++ai) {
        const auto [compared, agreed] = counts[ai];
        if (compared >= kMinComparedToDiscard && agreed == 0 && out.agreed > 0) {
            discardWholeTraverse(all[ai].t->name, compared, out);
        }
    }
    out.median_m = quantile(agreed_m, 0.5);
    out.p95_m = quantile(agreed_m, 0.95);
    out.max_agreed_m = agreed_m.empty() ? 0 : *std::max_element(agreed_m.begin(), agreed_m.end());
    if (out.compared == 0) out.note = "no two traverses passed under the same ceiling";
    out.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    return out;
}

nlohmann::ordered_json poseAuditJson(const PoseAudit& a) {
    nlohmann::ordered_json j{{"ran", a.ran},
                             {"note", a.note},
                             {"sampled", a.sampled},
                             {"compared", a.compared},
                             {"agreed", a.agreed},
                             {"disagreed", a.disagreed},
                             {"inconclusive", a.inconclusive},
                             {"suspect", a.suspect},
                             {"traverses_discarded", a.traverses_discarded},
                             {"agreed_median_m", a.median_m},
                             {"agreed_p95_m", a.p95_m},
                             {"agreed_max_m", a.max_agreed_m},
                             {"time_s", a.time_s}};
    j["suspect_stretches"] = nlohmann::ordered_json::array();
    for (const auto& s : a.stretches) {
        j["suspect_stretches"].push_back(
            {{"traverse", s.traverse},
             {"sample_time_s", s.sample_s},
             {"from_time_s", s.from_s > -1e299 ? nlohmann::ordered_json(s.from_s) : nullptr},
             {"to_time_s", s.to_s < 1e299 ? nlohmann::ordered_json(s.to_s) : nullptr},
             {"disagreement_m", s.disagreement_m},
             {"against", s.against},
             {"whole_traverse_compared", s.whole_traverse_compared}});
    }
    return j;
}

}  // namespace lookup::survey
