#pragma once
// Strict checking of the survey.ini sections MRPT reads itself (ICP-SLAM, ICP, MCL): MRPT's
// loadFromConfigFile ignores unknown keys and reads malformed numbers as 0, so a typo or
// `thresholdDist = abc` would silently change the laser poses.

#include <mrpt/config/CConfigFileBase.h>

namespace lookup::survey {

/// Throws common::ConfigError naming the file, section and key for a key MRPT does not read
/// in [MappingApplication] (and its map sub-sections), [ICP], [PF_options], [KLD_options] or
/// [LikelihoodOptions], and for a value that is not a finite number where MRPT reads a number,
/// or not a boolean where it reads a boolean.
void checkMrptSections(const mrpt::config::CConfigFileBase& config);

}  // namespace lookup::survey
