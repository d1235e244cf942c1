#include "lookup/survey/mrpt_sections.h"

#include <mrpt/bayes/CParticleFilter.h>
#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/maps/CPointsMap.h>
#include <mrpt/slam/CICP.h>
#include <mrpt/slam/CMetricMapBuilderICP.h>
#include <mrpt/slam/TKLDParams.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <map>
#include <vector>

#include "lookup/common/config.h"
#include "lookup/common/errors.h"

namespace lookup::survey {
namespace {

// Sub-sections of [MappingApplication] that define the ICP-SLAM maps: their numeric values.
void checkNumericSection(const mrpt::config::CConfigFileBase& config, const std::string& section,
                         const std::vector<std::string>& known) {
    if (!config.sectionExists(section)) return;
    const common::IniSection s(config, section);
    if (!known.empty()) s.rejectUnknownKeys(known);
    std::vector<std::string> keys;
    config.getAllKeys(section, keys);
    for (const auto& key : keys) {
        const std::string value = s.getString(key, "");
        char* end = nullptr;
        const double v = std::strtod(value.c_str(), &end);
        if (end == value.c_str() || *end != '\0' || !std::isfinite(v)) {
            throw common::ConfigError(s.where(key) + "'" + value + "' is not a finite number");
        }
    }
}

template <class Options>
void checkSection(const mrpt::config::CConfigFileBase& config, const std::string& section,
                  Options&& options, const std::vector<std::string>& extra = {}) {
    common::checkMrptSection(
        config, section,
        [&](const mrpt::config::CConfigFileBase& view) {
            options.loadFromConfigFile(view, section);
        },
        extra);
}

}  // namespace

void checkMrptSections(const mrpt::config::CConfigFileBase& config) {
    mrpt::system::VerbosityLevel verbosity = mrpt::system::LVL_ERROR;
    checkSection(config, "MappingApplication",
                 mrpt::slam::CMetricMapBuilderICP::TConfigParams(verbosity),
                 {"occupancygrid_count", "pointsmap_count", "gasgrid_count", "landmarksmap_count",
                  "beaconmap_count", "heightmap_count", "colourpointsmap_count",
                  "weightedpointsmap_count", "likelihoodmapselection"});
    checkSection(config, "ICP", mrpt::slam::CICP::TConfigParams());
    checkSection(config, "PF_options", mrpt::bayes::CParticleFilter::TParticleFilterOptions());
    checkSection(config, "KLD_options", mrpt::slam::TKLDParams());
    checkSection(config, "LikelihoodOptions",
                 mrpt::maps::COccupancyGridMap2D::TLikelihoodOptions());
    checkSection(config, "MappingApplication_occupancyGrid_00_insertOpts",
                 mrpt::maps::COccupancyGridMap2D::TInsertionOptions());
    checkSection(config, "MappingApplication_pointsMap_00_insertOpts",
                 mrpt::maps::CPointsMap::TInsertionOptions());
    checkNumericSection(config, "MappingApplication_occupancyGrid_00_creationOpts",
                        {"resolution", "min_x", "max_x", "min_y", "max_y"});
}

}  // namespace lookup::survey
