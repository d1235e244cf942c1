#include "lookup/common/camera_params.h"

#include <mrpt/config/CConfigFile.h>
#include <mrpt/core/exceptions.h>
#include <mrpt/obs/CObservationImage.h>

#include <filesystem>

#include "lookup/common/config.h"

namespace fs = std::filesystem;

namespace lookup::common {

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
