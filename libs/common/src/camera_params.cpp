#include "lookup/common/camera_params.h"

#include <mrpt/config/CConfigFile.h>
#include <mrpt/core/exceptions.h>
#include <mrpt/obs/CObservationImage.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "lookup/common/config.h"

namespace fs = std::filesystem;

namespace lookup::common {
namespace {

std::string number(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
}

std::string size(unsigned w, unsigned h) { return std::to_string(w) + "x" + std::to_string(h); }

bool knownModel(mrpt::img::DistortionModel m) {
    using M = mrpt::img::DistortionModel;
    return m == M::none || m == M::plumb_bob || m == M::kannala_brandt;
}

}  // namespace

std::string cameraProblem(const mrpt::img::TCamera& c, int width, int height) {
    if (!std::isfinite(c.fx()) || !std::isfinite(c.fy()) || !(c.fx() > 0) || !(c.fy() > 0)) {
        return "focal length fx = " + number(c.fx()) + ", fy = " + number(c.fy()) +
               " is not finite and > 0";
    }
    if (!std::isfinite(c.cx()) || !std::isfinite(c.cy())) {
        return "principal point cx = " + number(c.cx()) + ", cy = " + number(c.cy()) +
               " is not finite";
    }
    if (!knownModel(c.distortion)) {
        return "distortion model " + std::to_string(int(c.distortion)) +
               " is not one MRPT knows (none, plumb_bob, kannala_brandt)";
    }
    for (std::size_t k = 0; k < c.dist.size(); ++k) {
        if (!std::isfinite(c.dist[k])) {
            return "distortion dist[" + std::to_string(k) + "] = " + number(c.dist[k]) +
                   " is not finite";
        }
    }
    if ((width > 0 || height > 0) && (int(c.ncols) != width || int(c.nrows) != height)) {
        return "intrinsics are for " + size(c.ncols, c.nrows) + " px but the image is " +
               size(unsigned(width), unsigned(height)) + " px";
    }
    return "";
}

mrpt::img::TCamera resizedCamera(const mrpt::img::TCamera& camera, int width, int height) {
    // MRPT's TCamera::scaleToResolution scales cx by the ratio alone: half a source pixel off
    // the centre cv::resize maps a pixel to, a shift that does not cancel between images stored
    // at different sizes.
    const double sx = double(width) / camera.ncols, sy = double(height) / camera.nrows;
    mrpt::img::TCamera out = camera;
    out.ncols = uint32_t(width);
    out.nrows = uint32_t(height);
    out.fx(camera.fx() * sx);
    out.fy(camera.fy() * sy);
    out.cx((camera.cx() + 0.5) * sx - 0.5);
    out.cy((camera.cy() + 0.5) * sy - 0.5);
    return out;
}

mrpt::img::TImageSize cappedSize(int width, int height, int max_width) {
    if (max_width <= 0 || width <= max_width) return {width, height};
    return {max_width, std::max(1, int(std::lround(double(height) * max_width / width)))};
}

std::optional<mrpt::img::TCamera> sensorCameraParams(const mrpt::config::CConfigFileBase& sensors,
                                                     const std::string& section,
                                                     const std::string& sensors_path) {
    const IniSection s(sensors, section, sensors_path);
    if (!s.has("camera_params_file")) return std::nullopt;
    fs::path file = s.requireString("camera_params_file");
    if (file.is_relative()) file = fs::path(sensors_path).parent_path() / file;
    if (!fs::is_regular_file(file)) {
        throw ConfigError(s.where("camera_params_file") + file.string() + ": no such file");
    }
    mrpt::config::CConfigFile calib(file.string());
    if (!calib.sectionExists("CAMERA_PARAMS")) {
        throw ConfigError(file.string() + ": no [CAMERA_PARAMS] section");
    }
    // MRPT 2.5 reads `dist` only with a distortion model: without one it drops it silently.
    if (calib.keyExists("CAMERA_PARAMS", "dist") &&
        !calib.keyExists("CAMERA_PARAMS", "distortion_model")) {
        throw ConfigError(file.string() +
                          " [CAMERA_PARAMS] dist: needs distortion_model = plumb_bob (MRPT "
                          "ignores dist without it)");
    }
    mrpt::img::TCamera camera;
    try {
        camera.loadFromConfigFile("CAMERA_PARAMS", calib);
    } catch (const std::exception& e) {
        throw ConfigError(file.string() + " [CAMERA_PARAMS]: " + mrpt::exception_to_str(e));
    }
    if (!(camera.fx() > 0 && camera.fy() > 0) || camera.ncols == 0 || camera.nrows == 0) {
        throw ConfigError(file.string() + " [CAMERA_PARAMS]: needs fx, fy > 0 and resolution");
    }
    return camera;
}

bool applyCameraParams(const mrpt::img::TCamera& camera, mrpt::obs::CObservation& obs) {
    auto* image = dynamic_cast<mrpt::obs::CObservationImage*>(&obs);
    if (image == nullptr) return false;
    if (!image->image.isExternallyStored() && !image->image.isEmpty() &&
        (image->image.getWidth() != camera.ncols || image->image.getHeight() != camera.nrows)) {
        throw ConfigError(obs.sensorLabel + ": image " + std::to_string(image->image.getWidth()) +
                          "x" + std::to_string(image->image.getHeight()) +
                          " px but the calibration is " + std::to_string(camera.ncols) + "x" +
                          std::to_string(camera.nrows));
    }
    image->cameraParams = camera;
    return true;
}

}  // namespace lookup::common
