#pragma once
// Internal to lookup::survey: a traverse's ceiling frames placed on its laser track, and the
// rectifier that shows them to the refiner as the localiser will see the stored references.
// Shared by the ceiling-height estimate and the pose audit.

#include <mrpt/poses/CPose3D.h>

#include <optional>
#include <vector>

#include "lookup/refine/rectifier.h"
#include "lookup/survey/ceiling_distance.h"

namespace lookup::survey::detail {

struct PosedCeilingFrame {
    double travel_m = 0;  ///< along the track from the first posed frame [m]
    mrpt::poses::CPose3D pose;
    std::size_t index = 0;  ///< into CeilingTraverse::ceiling
};

/// The frames of `t` with a pose on its track, in time order.
std::vector<PosedCeilingFrame> posedCeilingFrames(const CeilingTraverse& t);

/// The frame whose travel is nearest `target_m` (`f` not empty).
std::size_t nearestTravel(const std::vector<PosedCeilingFrame>& f, double target_m);

/// Every image rectified into the first valid camera's pinhole twin at the width the references
/// are stored at; none when no image has a valid camera.
std::optional<refine::Rectifier> storedCameraRectifier(
    const std::vector<CeilingTraverse>& traverses, const SurveyOptions& o);

}  // namespace lookup::survey::detail
