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
    CoarseOptions options;
    if (!ini_.empty()) {
        const auto file = common::loadIniFile(ini_);  // missing, binary or garbled: refused
        common::rejectUnknownSections(*file, {section_});
        options.loadFromConfigFile(*file, section_);
    }
    if (!camera_.empty()) options.camera_label = camera_;
    try {
        options.check();
    } catch (const common::ConfigError& e) {
        if (ini_.empty()) throw;
        throw common::ConfigError(ini_ + " [" + section_ + "]: " + e.what());
    }

    std::optional<common::PoseTrack> ref_track, query_track;
    if (!ref_poses_.empty()) ref_track = common::readPoseFile(ref_poses_);
    if (!query_poses_.empty()) query_track = common::readPoseFile(query_poses_);

    std::shared_ptr<ReferenceDescriptors> refs;
    if (!ref_descriptors_.empty()) {
        refs = std::make_shared<ReferenceDescriptors>(
            ReferenceDescriptors::loadDescriptors(ref_descriptors_));
    } else {
        if (!quiet_) err << "Reading references from " << ref_rawlog_ << "\n";
        refs = std::make_shared<ReferenceDescriptors>(
            buildReferenceSequence(ref_rawlog_, options, ref_track ? &*ref_track : nullptr, 1.0));
    }
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

    // Count the query images first, for the progress bar (cheap: images are not loaded).
    std::size_t total = 0;
    if (!quiet_) {
        common::RawlogReader counter(query_rawlog_);
        mrpt::obs::CObservation::Ptr obs;
        while (counter.next(obs)) total += obs->sensorLabel == options.camera_label ? 1 : 0;
    }
    CameraFrameStream stream(query_rawlog_, options.camera_label, odometry_label_);

    const std::string tmp = out_csv_ + ".tmp";
    std::ofstream csv(tmp);
    if (!csv) throw common::WriteError(tmp, "cannot open for writing");
    const bool evaluate = query_truth && refs->hasPoses();
    csv << "query_index,query_time_s,reference_index,reference_time_s,confidence,status"
        << (evaluate ? ",error_m" : "") << ",reason\n";
    csv << std::setprecision(15);

    std::vector<double> frame_ms, search_ms, errors;
    std::vector<Descriptor> query_descriptors;
    std::vector<CoarseResult> results;
    std::vector<std::size_t> truth;
    CameraFrame frame;
    while (stream.next(frame)) {
        const auto& image = frame.observation->image;
        if (refs->imageWidth() > 0 && (stream.imageWidth() != refs->imageWidth() ||
                                       stream.imageHeight() != refs->imageHeight())) {
            throw common::RawlogError(
                query_rawlog_, frame.record,
                "query images are " + std::to_string(stream.imageWidth()) + "x" +
                    std::to_string(stream.imageHeight()) + ", reference images are " +
                    std::to_string(refs->imageWidth()) + "x" + std::to_string(refs->imageHeight()));
        }
        CoarseResult r = localizer.process(image, frame.time_s, frame.travelled_m);
        if (!confusion_png_.empty()) {
            query_descriptors.push_back(computeDescriptor(image, options));
        }
        image.unload();
        frame_ms.push_back(r.descriptor_ms + r.search_ms);
        search_ms.push_back(r.search_ms);
        if (r.status == CoarseStatus::kTracking || r.status == CoarseStatus::kOdometry) {
            ++summary_.tracking_frames;
            summary_.mean_tracking_search_ms += r.search_ms;
        } else if (r.status != CoarseStatus::kInvalidInput &&
                   r.status != CoarseStatus::kNotSearched) {
            ++summary_.global_frames;
            summary_.mean_global_search_ms += r.search_ms;
        }

        std::optional<double> error;
        std::size_t true_ref = CoarseResult::kNone;
        if (evaluate) {
            mrpt::poses::CPose3D truth_pose;
            bool valid = false;
            query_truth->interpolate(mrpt::Clock::fromDouble(frame.time_s), truth_pose, valid);
            if (valid) {
                // (A scan of every reference: only for the picture, it would cost more than
                // the search on a long reference and cool the caches the timing measures.)
                if (!confusion_png_.empty()) true_ref = refs->nearestInSpace(truth_pose);
                if (r.hasMatch()) {
                    const auto& p = refs->pose(r.reference_index);
                    error = std::hypot(p.x() - truth_pose.x(), p.y() - truth_pose.y());
                    errors.push_back(*error);
                }
            }
        }
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

        ++summary_.frames;
        if (r.usable()) ++summary_.usable;
        if (r.status == CoarseStatus::kGlobal) ++summary_.global_searches;
        if (r.status == CoarseStatus::kOdometry) ++summary_.odometry;
        if (r.status == CoarseStatus::kUnconfirmed) ++summary_.unconfirmed;
        if (r.status == CoarseStatus::kLost || r.status == CoarseStatus::kInvalidInput) {
            ++summary_.lost;
        }
        if (r.status == CoarseStatus::kNotEnoughFrames) ++summary_.not_enough;
        if (!confusion_png_.empty()) {
            results.push_back(r);
            truth.push_back(true_ref);
        }
        if (!quiet_ && total > 0 && (summary_.frames % 20 == 0 || summary_.frames == total)) {
            err << "\r" << mrpt::system::progress(double(summary_.frames) / total, 30) << " "
                << summary_.frames << "/" << total << " usable " << summary_.usable << std::flush;
        }
    }
    csv.close();
    if (!csv) throw common::WriteError(tmp, "write failed (disk full?)");
    common::syncFile(tmp);  // a power cut leaves the old file or the whole new one
    std::error_code ec;
    std::filesystem::rename(tmp, out_csv_, ec);
    if (ec)
        throw common::WriteError(out_csv_, "cannot rename " + tmp + " into place: " + ec.message());
    if (!quiet_) err << "\n";

    summary_.mean_frame_ms = mean(frame_ms);
    summary_.median_frame_ms = median(frame_ms);
    summary_.mean_search_ms = mean(search_ms);
    summary_.median_search_ms = median(search_ms);
    if (summary_.tracking_frames > 0) summary_.mean_tracking_search_ms /= summary_.tracking_frames;
    if (summary_.global_frames > 0) summary_.mean_global_search_ms /= summary_.global_frames;
    if (!errors.empty()) {
        summary_.evaluated = errors.size();
        summary_.mean_error_m = mean(errors);
        summary_.median_error_m = median(errors);
        summary_.share_over_10m =
            static_cast<double>(
                std::count_if(errors.begin(), errors.end(), [](double e) { return e > 10.0; })) /
            errors.size();
    }
    if (!confusion_png_.empty()) {
        ConfusionImageOptions png;
        png.contrast_window_refs = options.contrast_window_refs;
        writeConfusionImage(confusion_png_, *refs, query_descriptors, results,
                            evaluate ? truth : std::vector<std::size_t>{}, png);
    }

    out << std::fixed << std::setprecision(3) << "references: " << summary_.references
        << (summary_.indexed ? " (global searches through the descriptor index"
                             : " (global searches over every reference")
        << "; set-up " << summary_.setup_ms << " ms)"
        << "\nquery frames: " << summary_.frames << " (usable " << summary_.usable
        << ", held by odometry " << summary_.odometry << ", global " << summary_.global_searches
        << ", unconfirmed " << summary_.unconfirmed << ", lost " << summary_.lost
        << ", not enough frames " << summary_.not_enough << ")"
        << "\ntime per frame [ms]: mean " << summary_.mean_frame_ms << ", median "
        << summary_.median_frame_ms << " (search only: mean " << summary_.mean_search_ms
        << ", median " << summary_.median_search_ms << ")"
        << "\nsearch time by frame [ms]: tracking mean " << summary_.mean_tracking_search_ms << " ("
        << summary_.tracking_frames << " frames), global mean " << summary_.mean_global_search_ms
        << " (" << summary_.global_frames << " frames)\n";
    if (summary_.evaluated > 0) {
        out << "coarse error [m] over " << summary_.evaluated << " frames: mean "
            << summary_.mean_error_m << ", median " << summary_.median_error_m << ", > 10 m "
            << 100.0 * summary_.share_over_10m << " %\n";
    }
    return 0;
}

}  // namespace lookup::coarse
