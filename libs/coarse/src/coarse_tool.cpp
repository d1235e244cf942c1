#include "lookup/coarse/coarse_tool.h"

#include <mrpt/3rdparty/tclap/CmdLine.h>
#include <mrpt/config/CConfigFile.h>
#include <mrpt/system/progress.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <numeric>
#include <optional>
#include <random>

#include "lookup/coarse/camera_stream.h"
#include "lookup/coarse/coarse_localizer.h"
#include "lookup/coarse/confusion_image.h"
#include "lookup/common/cli.h"
#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/common/options_table.h"
#include "lookup/common/rawlog_io.h"

namespace lookup::coarse {
namespace {

double median(std::vector<double> v) {
    if (v.empty()) return 0;
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
}

double mean(const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x;
    return v.empty() ? 0 : s / v.size();
}

/// Appends `copies - 1` altered copies of the references (thumbnail pixels randomly
/// permuted, poses moved 100 km away): a longer database with no exact duplicates, for
/// measuring how the cost grows with the database length.
ReferenceDescriptors replicate(const ReferenceDescriptors& refs, int copies) {
    ReferenceDescriptors out(refs.layout());
    out.setImageSize(refs.imageWidth(), refs.imageHeight());
    const int w = refs.layout().thumb_width_px, h = refs.layout().thumb_height_px;
    const double span = refs.time(refs.size() - 1) - refs.time(0) + 1.0;
    std::vector<std::vector<std::size_t>> perms(copies);
    std::mt19937 rng(7);
    for (auto& p : perms) {
        p.resize(static_cast<std::size_t>(w) * h);
        std::iota(p.begin(), p.end(), 0);
        std::shuffle(p.begin(), p.end(), rng);
    }
    for (int c = 0; c < copies; ++c) {
        for (std::size_t i = 0; i < refs.size(); ++i) {
            Descriptor d = refs.descriptor(i);
            if (c > 0) {  // a fixed random permutation per copy: no copy resembles a place
                Descriptor s(d.size());
                for (std::size_t k = 0; k < d.size(); ++k) s[k] = d[perms[c][k]];
                d = std::move(s);
            }
            std::optional<mrpt::poses::CPose3D> pose;
            if (refs.hasPoses()) {
                pose = refs.pose(i);
                pose->x_incr(1e5 * c);
            }
            out.add(refs.time(i) + c * span, std::move(d), pose);
        }
    }
    return out;
}

/// [section] of `ini` (defaults without one), the camera label overridden by `camera`; errors
/// name the file and section.
CoarseOptions loadOptions(const std::string& ini, const std::string& section,
                          const std::string& camera) {
    CoarseOptions options;
    if (!ini.empty()) {
        const auto file = common::loadIniFile(ini);  // missing, binary or garbled: refused
        common::rejectUnknownSections(*file, {section});
        options.loadFromConfigFile(*file, section);
    }
    if (!camera.empty()) options.camera_label = camera;
    try {
        options.check();
    } catch (const common::ConfigError& e) {
        if (ini.empty()) throw;
        throw common::ConfigError(ini + " [" + section + "]: " + e.what());
    }
    return options;
}

/// Number of images of `label` in `rawlog`, for the progress bar (cheap: images are not
/// loaded).
std::size_t countImages(const std::string& rawlog, const std::string& label) {
    std::size_t total = 0;
    common::RawlogReader counter(rawlog);
    mrpt::obs::CObservation::Ptr obs;
    while (counter.next(obs)) total += obs->sensorLabel == label ? 1 : 0;
    return total;
}

/// Refuses a query frame whose size differs from the references' images.
void checkImageSize(const CameraFrameStream& stream, const CameraFrame& frame,
                    const ReferenceDescriptors& refs, const std::string& rawlog) {
    if (refs.imageWidth() == 0 ||
        (stream.imageWidth() == refs.imageWidth() && stream.imageHeight() == refs.imageHeight())) {
        return;
    }
    throw common::RawlogError(rawlog, frame.record,
                              "query images are " + std::to_string(stream.imageWidth()) + "x" +
                                  std::to_string(stream.imageHeight()) + ", reference images are " +
                                  std::to_string(refs.imageWidth()) + "x" +
                                  std::to_string(refs.imageHeight()));
}

void writeCsvHeader(std::ostream& csv, bool evaluate) {
    csv << "query_index,query_time_s,reference_index,reference_time_s,confidence,status"
        << (evaluate ? ",error_m" : "") << ",reason\n";
    csv << std::setprecision(15);
}

void writeCsvRow(std::ostream& csv, const CoarseResult& r, bool evaluate,
                 std::optional<double> error) {
    csv << r.query_index << "," << r.query_time_s << ",";
    if (r.hasMatch())
        csv << r.reference_index << "," << r.reference_time_s;
    else
        csv << ",";
    csv << "," << r.confidence << "," << toString(r.status);
    if (evaluate) {
        csv << ",";
        if (error) csv << *error;
    }
    std::string reason = r.reason;
    std::replace(reason.begin(), reason.end(), '"', '\'');
    csv << ",\"" << reason << "\"\n";
}

/// Closes `csv` (written to `tmp`), syncs it and renames it to `path`: a power cut leaves the
/// old file or the whole new one.
void commitCsv(std::ofstream& csv, const std::string& tmp, const std::string& path) {
    csv.close();
    if (!csv) throw common::WriteError(tmp, "write failed (disk full?)");
    common::syncFile(tmp);
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) throw common::WriteError(path, "cannot rename " + tmp + " into place: " + ec.message());
}

/// Counts one frame's result in the run's figures (search times summed; see summarise).
void countResult(const CoarseResult& r, CoarseRunSummary& s) {
    if (r.status == CoarseStatus::Tracking || r.status == CoarseStatus::Odometry) {
        ++s.tracking_frames;
        s.mean_tracking_search_ms += r.search_ms;
    } else if (r.status != CoarseStatus::InvalidInput && r.status != CoarseStatus::NotSearched) {
        ++s.global_frames;
        s.mean_global_search_ms += r.search_ms;
    }
    ++s.frames;
    if (r.usable()) ++s.usable;
    if (r.status == CoarseStatus::Global) ++s.global_searches;
    if (r.status == CoarseStatus::Odometry) ++s.odometry;
    if (r.status == CoarseStatus::Unconfirmed) ++s.unconfirmed;
    if (r.status == CoarseStatus::Lost || r.status == CoarseStatus::InvalidInput) ++s.lost;
    if (r.status == CoarseStatus::NotEnoughFrames) ++s.not_enough;
}

/// Per-frame times and errors of a run.
struct FrameFigures {
    std::vector<double> frame_ms, search_ms, errors;
};

/// Means and medians of the run's figures into `s`.
void summarise(const FrameFigures& f, CoarseRunSummary& s) {
    s.mean_frame_ms = mean(f.frame_ms);
    s.median_frame_ms = median(f.frame_ms);
    s.mean_search_ms = mean(f.search_ms);
    s.median_search_ms = median(f.search_ms);
    if (s.tracking_frames > 0) s.mean_tracking_search_ms /= s.tracking_frames;
    if (s.global_frames > 0) s.mean_global_search_ms /= s.global_frames;
    if (f.errors.empty()) return;
    s.evaluated = f.errors.size();
    s.mean_error_m = mean(f.errors);
    s.median_error_m = median(f.errors);
    s.share_over_10m = static_cast<double>(std::count_if(f.errors.begin(), f.errors.end(),
                                                         [](double e) { return e > 10.0; })) /
                       f.errors.size();
}

void printSummary(std::ostream& out, const CoarseRunSummary& s) {
    out << std::fixed << std::setprecision(3) << "references: " << s.references
        << (s.indexed ? " (global searches through the descriptor index"
                      : " (global searches over every reference")
        << "; set-up " << s.setup_ms << " ms)"
        << "\nquery frames: " << s.frames << " (usable " << s.usable << ", held by odometry "
        << s.odometry << ", global " << s.global_searches << ", unconfirmed " << s.unconfirmed
        << ", lost " << s.lost << ", not enough frames " << s.not_enough << ")"
        << "\ntime per frame [ms]: mean " << s.mean_frame_ms << ", median " << s.median_frame_ms
        << " (search only: mean " << s.mean_search_ms << ", median " << s.median_search_ms << ")"
        << "\nsearch time by frame [ms]: tracking mean " << s.mean_tracking_search_ms << " ("
        << s.tracking_frames << " frames), global mean " << s.mean_global_search_ms << " ("
        << s.global_frames << " frames)\n";
    if (s.evaluated > 0) {
        out << "coarse error [m] over " << s.evaluated << " frames: mean " << s.mean_error_m
            << ", median " << s.median_error_m << ", > 10 m " << 100.0 * s.share_over_10m << " %\n";
    }
}

/// What the confusion picture needs, collected per frame when it is asked for.
struct ConfusionInputs {
    std::vector<Descriptor> query_descriptors;
    std::vector<CoarseResult> results;
    std::vector<std::size_t> truth;  ///< reference nearest to the query's true pose
};

/// The references: saved descriptors, or the reference rawlog's images (with their poses when
/// `track` is given).
std::shared_ptr<ReferenceDescriptors> loadReferences(const std::string& descriptors_file,
                                                     const std::string& rawlog,
                                                     const CoarseOptions& options,
                                                     const common::PoseTrack* track, bool quiet,
                                                     std::ostream& err) {
    if (!descriptors_file.empty()) {
        return std::make_shared<ReferenceDescriptors>(
            ReferenceDescriptors::loadDescriptors(descriptors_file));
    }
    if (!quiet) err << "Reading references from " << rawlog << "\n";
    return std::make_shared<ReferenceDescriptors>(
        buildReferenceSequence(rawlog, options, track, 1.0));
}

/// The matched reference's planar distance from the query's true pose at `time_s`, when the
/// truth covers that time and there is a match. `nearest` (when asked for) gets the reference
/// nearest to the true pose: a scan of every reference, only for the picture (it would cost
/// more than the search on a long reference and cool the caches the timing measures).
std::optional<double> matchError(const CoarseResult& r, const ReferenceDescriptors& refs,
                                 const mrpt::poses::CPose3DInterpolator& truth, double time_s,
                                 bool want_nearest, std::size_t& nearest) {
    const auto truth_pose = common::poseAt(truth, time_s);
    if (!truth_pose) return std::nullopt;
    if (want_nearest) nearest = refs.nearestInSpace(*truth_pose);
    if (!r.hasMatch()) return std::nullopt;
    const auto& p = refs.pose(r.reference_index);
    return std::hypot(p.x() - truth_pose->x(), p.y() - truth_pose->y());
}
}  // namespace

bool CoarseTool::initialize(const std::vector<std::string>& args) {
    std::vector<const char*> argv;
    for (const auto& a : args) argv.push_back(a.c_str());
    return initialize(static_cast<int>(argv.size()), argv.data());
}

bool CoarseTool::initialize(int argc, const char* const* argv) {
    TCLAP::CmdLine cmd(std::string("lookup-coarse: online SeqSLAM coarse localisation of a query "
                                   "rawlog's forward-camera images against a reference rawlog; "
                                   "one CSV row per query image. ") +
                           common::kExitCodesHelp,
                       ' ', "0.1");
    lookup::common::OneLineOutput one_line_errors;
    cmd.setOutput(&one_line_errors);
    TCLAP::ValueArg<std::string> ref("", "ref", "Reference rawlog", false, "", "REF.rawlog", cmd);
    TCLAP::ValueArg<std::string> ref_desc("", "ref-descriptors",
                                          "Reference descriptors saved before (instead of --ref)",
                                          false, "", "FILE", cmd);
    TCLAP::ValueArg<std::string> query("", "query", "Query rawlog", true, "", "QUERY.rawlog", cmd);
    TCLAP::ValueArg<std::string> out("", "out", "Output CSV", true, "", "matches.csv", cmd);
    TCLAP::ValueArg<std::string> camera("", "camera",
                                        "Camera sensor label (overrides the ini; default "
                                        "FORWARD_CAM)",
                                        false, "", "LABEL", cmd);
    TCLAP::ValueArg<std::string> ini(
        "", "ini", "Options file (default: built-in defaults, as share/lookup/coarse.ini)", false,
        "", "FILE", cmd);
    TCLAP::ValueArg<std::string> section("", "section", "Section of --ini", false, "coarse", "NAME",
                                         cmd);
    TCLAP::ValueArg<std::string> ref_poses(
        "", "ref-poses",
        "Surveyed poses of the reference (MRPT GT or TUM): enables odometry-narrowed search "
        "and the error evaluation",
        false, "", "FILE", cmd);
    TCLAP::ValueArg<std::string> query_poses(
        "", "query-poses", "Ground-truth poses of the query, for the error evaluation only", false,
        "", "FILE", cmd);
    TCLAP::ValueArg<std::string> odo("", "odometry-label",
                                     "Odometry label in the query rawlog ('' disables)", false,
                                     "ODOMETRY", "LABEL", cmd);
    TCLAP::ValueArg<std::string> save(
        "", "save-descriptors", "Save the reference descriptors to FILE", false, "", "FILE", cmd);
    TCLAP::ValueArg<std::string> png("", "confusion-png",
                                     "Write the confusion matrix with the chosen path (PNG)", false,
                                     "", "FILE", cmd);
    TCLAP::ValueArg<int> replicate("", "replicate-reference",
                                   "Benchmarking aid: make the reference N times longer with "
                                   "altered copies",
                                   false, 1, "N", cmd);
    TCLAP::SwitchArg quiet("", "quiet", "No progress bar", cmd, false);
    TCLAP::SwitchArg verbose("", "verbose", "On errors, print MRPT's full exception dump", cmd,
                             false);

    if (!cmd.parse(argc, const_cast<const char**>(argv))) {
        exit_code_ = common::parseFailureExitCode(argc, argv);
        return false;
    }
    ref_rawlog_ = ref.getValue();
    ref_descriptors_ = ref_desc.getValue();
    query_rawlog_ = query.getValue();
    out_csv_ = out.getValue();
    camera_ = camera.getValue();
    ini_ = ini.getValue();
    section_ = section.getValue();
    ref_poses_ = ref_poses.getValue();
    query_poses_ = query_poses.getValue();
    odometry_label_ = odo.getValue();
    save_descriptors_ = save.getValue();
    confusion_png_ = png.getValue();
    replicate_ = replicate.getValue();
    quiet_ = quiet.getValue();
    verbose_ = verbose.getValue();
    if (ref_rawlog_.empty() == ref_descriptors_.empty()) {
        std::cerr << "lookup-coarse: give exactly one of --ref and --ref-descriptors\n";
        exit_code_ = 1;
        return false;
    }
    if (replicate_ < 1) {
        std::cerr << "lookup-coarse: --replicate-reference must be >= 1\n";
        exit_code_ = 1;
        return false;
    }
    return true;
}

int CoarseTool::run() { return run(std::cout, std::cerr); }

int CoarseTool::run(std::ostream& out, std::ostream& err) {
    try {
        exit_code_ = runOrThrow(out, err);
    } catch (const std::exception& e) {
        err << "lookup-coarse: error: " << common::errorText(e, verbose_) << "\n";
        exit_code_ = common::exitCodeFor(e);
        std::error_code ec;  // no half-written output left behind
        std::filesystem::remove(out_csv_ + ".tmp", ec);
    }
    return exit_code_;
}

int CoarseTool::runOrThrow(std::ostream& out, std::ostream& err) {
    const CoarseOptions options = loadOptions(ini_, section_, camera_);

    std::optional<common::PoseTrack> ref_track, query_track;
    if (!ref_poses_.empty()) ref_track = common::readPoseFile(ref_poses_);
    if (!query_poses_.empty()) query_track = common::readPoseFile(query_poses_);
    auto refs = loadReferences(ref_descriptors_, ref_rawlog_, options,
                               ref_track ? &*ref_track : nullptr, quiet_, err);
    if (!save_descriptors_.empty()) refs->saveDescriptors(save_descriptors_);
    if (replicate_ > 1) refs = std::make_shared<ReferenceDescriptors>(replicate(*refs, replicate_));
    summary_.references = refs->size();

    const auto setup_start = std::chrono::steady_clock::now();
    CoarseLocalizer localizer(refs, options);
    summary_.setup_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - setup_start)
            .count();
    summary_.indexed = localizer.indexed();

    std::optional<mrpt::poses::CPose3DInterpolator> query_truth;
    if (query_track) query_truth = common::makeInterpolator(*query_track, 1.0);
    const std::size_t total = quiet_ ? 0 : countImages(query_rawlog_, options.camera_label);
    CameraFrameStream stream(query_rawlog_, options.camera_label, odometry_label_);

    const std::string tmp = out_csv_ + ".tmp";
    std::ofstream csv(tmp);
    if (!csv) throw common::WriteError(tmp, "cannot open for writing");
    const bool evaluate = query_truth && refs->hasPoses();
    writeCsvHeader(csv, evaluate);
    const bool picture = !confusion_png_.empty();
    FrameFigures figures;
    ConfusionInputs confusion;
    CameraFrame frame;
    while (stream.next(frame)) {
        checkImageSize(stream, frame, *refs, query_rawlog_);
        const auto& image = frame.observation->image;
        const CoarseResult r = localizer.process(image, frame.time_s, frame.travelled_m);
        if (picture) confusion.query_descriptors.push_back(computeDescriptor(image, options));
        image.unload();
        figures.frame_ms.push_back(r.descriptor_ms + r.search_ms);
        figures.search_ms.push_back(r.search_ms);
        std::optional<double> error;
        std::size_t true_ref = CoarseResult::kNone;
        if (evaluate) error = matchError(r, *refs, *query_truth, frame.time_s, picture, true_ref);
        if (error) figures.errors.push_back(*error);
        writeCsvRow(csv, r, evaluate, error);
        countResult(r, summary_);
        if (picture) {
            confusion.results.push_back(r);
            confusion.truth.push_back(true_ref);
        }
        if (!quiet_ && total > 0 && (summary_.frames % 20 == 0 || summary_.frames == total)) {
            err << "\r" << mrpt::system::progress(double(summary_.frames) / total, 30) << " "
                << summary_.frames << "/" << total << " usable " << summary_.usable << std::flush;
        }
    }
    commitCsv(csv, tmp, out_csv_);
    if (!quiet_) err << "\n";
    summarise(figures, summary_);
    if (picture) {
        ConfusionImageOptions png;
        png.contrast_window_refs = options.contrast_window_refs;
        writeConfusionImage(confusion_png_, *refs, confusion.query_descriptors, confusion.results,
                            evaluate ? confusion.truth : std::vector<std::size_t>{}, png);
    }
    printSummary(out, summary_);
    return 0;
}

}  // namespace lookup::coarse
