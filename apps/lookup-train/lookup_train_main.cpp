// lookup-train: self-supervised training of the FCN sample-point selector (paper Sec. III-B)
// and heat maps for every reference of a database.
//   lookup-train --db DB --train QUERY.rawlog[,...] [--ini FILE] [--out-model FILE]
//                [--out DIR] [--init-model FILE] [--no-heatmaps] [--quiet]

#include <mrpt/3rdparty/tclap/CmdLine.h>
#include <mrpt/config/CConfigFile.h>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <sstream>

#include <opencv2/imgcodecs.hpp>

#include "lookup/common/cli.h"
#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/common/options_table.h"
#include "lookup/common/share_dirs.h"
#include "lookup/database/heat_maps.h"
#include "lookup/database/reference_database.h"
#include "lookup/fcn/heat_maps.h"
#include "lookup/fcn/model.h"
#include "lookup/fcn/train_app.h"
#include "lookup/refine/sampler.h"

namespace {

std::vector<std::string> splitList(const std::string& s) {
    std::vector<std::string> out;
    std::stringstream in(s);
    for (std::string item; std::getline(in, item, ',');) {
        if (!item.empty()) out.push_back(item);
    }
    return out;
}

// --ini, else share/lookup/train.ini (beside the binary, source tree, install prefix), else
// built-in defaults.
std::string defaultIni() {
    const std::string f = lookup::common::findShareFile("train.ini");
    return std::filesystem::is_regular_file(f) ? f : "";
}

// The reference's stored heat map (as the localiser loads it) and the points it would sample
// (refiner.ini defaults: 12 points, rho 0.5, l_n 10 px, 20 px margin).
void drawFigure(const std::string& db_dir, int index, const std::string& png) {
    const auto db = lookup::database::ReferenceDatabase::load(db_dir);
    if (db.size() == 0) throw std::runtime_error(db_dir + ": no references");
    const std::size_t i = index < 0 ? db.size() / 2 : std::size_t(index);
    if (i >= db.size()) throw std::runtime_error(db_dir + ": no reference " + std::to_string(i));
    const cv::Mat heat = lookup::database::loadHeatMap(db, i);
    if (heat.empty()) throw std::runtime_error(db_dir + "/db.ini: no heat maps (train first)");
    const lookup::refine::SamplerOptions s;
    const auto points = lookup::refine::heatMapPoints(heat, s.heat_map_points, s.damping_ratio,
                                                      s.damping_side_px, s.heatMapMargin());
    if (!cv::imwrite(png, lookup::fcn::heatMapFigure(db.ceilingImage(i), heat, points))) {
        throw lookup::common::WriteError(png, "cannot write the figure");
    }
    std::printf("%s: reference %zu of %s\n", png.c_str(), i, db_dir.c_str());
}

}  // namespace

int main(int argc, char** argv) {
    return lookup::common::guardedMain("lookup-train", argc, argv, [&] {
        TCLAP::CmdLine cmd(std::string("lookup-train: FCN sample-point selector (LibTorch) and "
                                       "heat maps. ") +
                               lookup::common::kExitCodesHelp,
                           ' ', "0.1");
        lookup::common::OneLineOutput one_line_errors;
        cmd.setOutput(&one_line_errors);
        TCLAP::ValueArg<std::string> db("", "db", "reference database folder", true, "", "DB", cmd);
        TCLAP::ValueArg<std::string> train("", "train",
                                           "training query rawlogs, comma separated (each with "
                                           "its .GT.txt); the last held_out_share of each is "
                                           "held out for evaluation (required unless "
                                           "--heatmaps-only)",
                                           false, "", "FILES", cmd);
        TCLAP::ValueArg<std::string> heat_only(
            "", "heatmaps-only",
            "no training: write the heat maps of DB's references with this trained model "
            "(e.g. one trained on another survey of the same mine)",
            false, "", "MODEL.pt", cmd);
        TCLAP::ValueArg<std::string> ini("", "ini",
                                         "options [fcn.network] [fcn.labels] [fcn.training] "
                                         "(default: share/lookup/train.ini)",
                                         false, "", "FILE", cmd);
        TCLAP::ValueArg<std::string> out_model(
            "", "out-model", "model file (default DB/fcn_model.pt)", false, "", "FILE", cmd);
        TCLAP::ValueArg<std::string> out("", "out",
                                         "folder for train_report.json and train_curve.png "
                                         "(default DB)",
                                         false, "", "DIR", cmd);
        TCLAP::ValueArg<std::string> init("", "init-model", "start from this model", false, "",
                                          "FILE", cmd);
        TCLAP::SwitchArg no_heat("", "no-heatmaps", "do not write heat maps into the database",
                                 cmd);
        TCLAP::SwitchArg quiet("", "quiet", "no progress bars", cmd);
        TCLAP::SwitchArg verbose("v", "verbose", "full error texts (MRPT call stacks)", cmd);
        TCLAP::ValueArg<std::string> figure("", "figure",
                                            "only draw reference --figure-ref beside its stored "
                                            "heat map and the 12 points the localiser samples "
                                            "into this PNG (no training)",
                                            false, "", "FILE.png", cmd);
        TCLAP::ValueArg<int> figure_ref("", "figure-ref", "reference index for --figure", false, -1,
                                        "N", cmd);
        if (!cmd.parse(argc, argv)) return lookup::common::parseFailureExitCode(argc, argv);
        if (!figure.getValue().empty()) {
            drawFigure(db.getValue(), figure_ref.getValue(), figure.getValue());
            return 0;
        }

        lookup::fcn::TrainOptions options;
        const std::string ini_file = ini.getValue().empty() ? defaultIni() : ini.getValue();
        if (!ini_file.empty()) {
            if (!std::filesystem::is_regular_file(ini_file)) {
                throw lookup::common::ConfigError(ini_file + ": no such file");
            }
            const auto cfg = lookup::common::loadIniFile(ini_file);
            lookup::common::rejectUnknownSections(*cfg,
                                                  lookup::fcn::TrainOptions::sectionNames("fcn"));
            lookup::common::loadAndCheck(options, *cfg, "fcn");
        }
        options.check();

        if (!heat_only.getValue().empty()) {
            const auto w = lookup::fcn::writeHeatMapsWithModel(db.getValue(), heat_only.getValue());
            std::printf("heat maps: %s/%s (%zu references, %.1f s) from %s\n",
                        db.getValue().c_str(), w.directory.c_str(), w.count, w.seconds,
                        heat_only.getValue().c_str());
            return 0;
        }
        if (train.getValue().empty()) {
            throw lookup::common::ConfigError(
                "--train FILES is required (or --heatmaps-only MODEL)");
        }

        lookup::fcn::TrainRequest req;
        req.db_dir = db.getValue();
        req.train_rawlogs = splitList(train.getValue());
        req.out_model = out_model.getValue();
        req.report_dir = out.getValue();
        req.init_model = init.getValue();
        req.write_heat_maps = !no_heat.getValue();
        req.progress = !quiet.getValue();
        const auto r = lookup::fcn::runTraining(req, options);

        std::printf(
            "labels: %zu pairs (%zu training, %zu held out), inlier share %.3f, %.1f s\n"
            "training: %zu images, %d epochs, val loss %.4f -> %.4f, %.1f s\n"
            "held out: best_point_inlier_share %.3f, random_point_inlier_share %.3f "
            "(%zu pairs)\n"
            "model: %s\nheat maps: %s (%zu)\nreport: %s\n",
            r.labels.usable_pairs, r.labels.training_pairs, r.labels.held_out_pairs,
            r.labels.inlierShare(), r.labels.seconds, r.training_samples,
            int(r.training.epochs.size()), r.training.initial_val_loss,
            r.training.epochs.empty() ? 0.0 : r.training.epochs.back().val_loss, r.training.seconds,
            r.evaluation.best_point_inlier_share, r.evaluation.random_point_inlier_share,
            r.evaluation.pairs, r.model_file.c_str(), r.heat_maps.directory.c_str(),
            r.heat_maps.count, r.report_file.c_str());
        for (const auto& w : r.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
        if (std::fflush(stdout) != 0 || std::ferror(stdout)) {
            throw lookup::common::WriteError("stdout", "cannot write the summary");
        }
        return 0;
    });
}
