#include <mrpt/img/CImage.h>

#include <stdexcept>

#include "lookup/common/grey.h"
#include "lookup/refine/matcher.h"
#include "lookup/refine/sampler.h"
#include "lookup/refine/types.h"

namespace lookup::refine {

void ReferenceImage::prepare(const MatcherOptions& matcher) {
    pyramid = std::make_shared<const ImagePyramid>(
        ImagePyramid::build(image, matcher.pyramid_levels, matcher));
}

void ReferenceImage::prepareSamplePoints(const SamplerOptions& options) {
    // A heat map the Refiner would refuse gets no cache: the Refiner then checks it per query
    // and names it in its reason. (The selection itself refuses a non-finite map with no
    // points.)
    sample_points.reset();
    if (!heat_map.empty() && (heat_map.type() != CV_32FC1 || heat_map.size() != image.size())) {
        return;
    }
    auto points = selectSamplePoints(image.size(), heat_map, options);
    if (!heat_map.empty() && points.empty()) return;
    sample_points = std::make_shared<const SamplePoints>(SamplePoints{options, std::move(points)});
}

ReferenceImage ReferenceImage::fromObservation(std::int64_t id,
                                               const mrpt::obs::CObservationImage& obs,
                                               const mrpt::poses::CPose3D& vehicle_in_map) {
    ReferenceImage r;
    r.id = id;
    r.timestamp = obs.timestamp;
    r.camera = obs.cameraParams;
    r.vehicle_in_map = vehicle_in_map;
    r.camera_on_vehicle = obs.cameraPose;
    try {
        const cv::Mat& m = obs.image.asCvMatRef();  // loads an external image
        r.image = m.channels() == 1 ? m.clone() : common::greyOf(m);
    } catch (const std::exception& e) {
        throw std::runtime_error("reference " + std::to_string(id) + " (label '" + obs.sensorLabel +
                                 "'): cannot read its image: " + e.what());
    }
    if (r.image.empty() || r.image.type() != CV_8UC1) {
        throw std::runtime_error("reference " + std::to_string(id) + " (label '" + obs.sensorLabel +
                                 "'): image is empty or not 8-bit");
    }
    return r;
}

}  // namespace lookup::refine
