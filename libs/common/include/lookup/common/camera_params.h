#pragma once
// Camera calibration for live camera sensors. MRPT's CCameraSensor (OpenCV, FFmpeg grabbers)
// does not fill CObservationImage::cameraParams, so a sensor section of sensors.ini names the
// calibration file instead: `camera_params_file = ceiling_calib.ini`, an MRPT camera file with
// a [CAMERA_PARAMS] section (resolution, cx, cy, fx, fy, dist: the file rawlog-edit
// --camera-params reads for recordings, written from camera-calib's results; docs/vehicle.md).
// rawlog-grabber ignores the key, so one sensors.ini serves recording and localising.

#include <mrpt/config/CConfigFileBase.h>
#include <mrpt/img/TCamera.h>
#include <mrpt/img/TPixelCoord.h>
#include <mrpt/obs/CObservation.h>

#include <optional>
#include <string>

namespace lookup::common {

/// The calibration named by `camera_params_file` in `section` of the sensors file
/// `sensors_path` (a relative file name is relative to the sensors file's folder);
/// std::nullopt when the section has no such key. Throws ConfigError naming the sensors file,
/// section and key, or the calibration file, when the file is missing or its [CAMERA_PARAMS]
/// are incomplete or invalid (fx, fy <= 0, resolution not two positive numbers).
std::optional<mrpt::img::TCamera> sensorCameraParams(const mrpt::config::CConfigFileBase& sensors,
                                                     const std::string& section,
                                                     const std::string& sensors_path);

/// Gives `obs`, when it is a CObservationImage, the intrinsics and distortion `camera`; returns
/// false for other observations. Throws ConfigError when the image (in memory) is not of the
/// calibrated resolution: the intrinsics would be silently wrong.
bool applyCameraParams(const mrpt::img::TCamera& camera, mrpt::obs::CObservation& obs);

/// Why `camera` cannot describe an image of `width` x `height` px, or "" when it can: focal
/// lengths not finite and > 0, a principal point or distortion coefficient not finite, a
/// distortion model MRPT does not know, or a calibrated size (ncols x nrows) other than the
/// image's. `width` = `height` = 0 skips the size check.
std::string cameraProblem(const mrpt::img::TCamera& camera, int width = 0, int height = 0);

/// The camera of `camera`'s images resized to `width` x `height` px (cv::resize's pixel-centre
/// convention: a pixel's centre x maps to (x + 0.5) * width / ncols - 0.5), distortion
/// coefficients unchanged (they act on normalised coordinates).
mrpt::img::TCamera resizedCamera(const mrpt::img::TCamera& camera, int width, int height);

/// An image of `width` x `height` px scaled down, aspect kept, to at most `max_width` columns
/// (0 = no limit); its own size when it is no wider.
mrpt::img::TImageSize cappedSize(int width, int height, int max_width);

}  // namespace lookup::common
