#include "lookup/coarse/reference_sequence.h"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>

#include "lookup/coarse/camera_stream.h"

namespace lookup::coarse {
namespace {

constexpr char kMagic[8] = {'L', 'K', 'C', 'O', 'A', 'R', 'S', 'E'};
constexpr std::uint32_t kVersion = 1;

template <typename T>
void put(std::ofstream& out, const T& v) {
    out.write(reinterpret_cast<const char*>(&v), sizeof(T));
}

template <typename T>
T get(std::ifstream& in, const std::string& path, const char* what) {
    T v{};
    if (!in.read(reinterpret_cast<char*>(&v), sizeof(T))) {
        throw DescriptorFileError(path + ": truncated while reading " + what);
    }
    return v;
}

}  // namespace

ReferenceDescriptors::ReferenceDescriptors(const CoarseOptions& options) : layout_(options) {
    layout_.check();
}

void ReferenceDescriptors::add(double time_s, Descriptor descriptor,
                               const std::optional<mrpt::poses::CPose3D>& pose) {
    const std::size_t expected =
        static_cast<std::size_t>(layout_.thumb_width_px) * layout_.thumb_height_px;
    if (descriptor.size() != expected) {
        throw std::invalid_argument("ReferenceDescriptors::add: frame " + std::to_string(size()) +
                                    " descriptor has " + std::to_string(descriptor.size()) +
                                    " values, expected " + std::to_string(expected));
    }
    if (!times_.empty() && time_s < times_.back()) {
        throw std::invalid_argument("ReferenceDescriptors::add: frame " + std::to_string(size()) +
                                    " time goes backwards");
    }
    if (!times_.empty() && pose.has_value() != hasPoses()) {
        throw std::invalid_argument("ReferenceDescriptors::add: frame " + std::to_string(size()) +
                                    " poses must be given for every frame or for none");
    }
    if (pose) {
        arc_.push_back(poses_.empty() ? 0.0 : arc_.back() + pose->distanceTo(poses_.back()));
        poses_.push_back(*pose);
    }
    times_.push_back(time_s);
    descriptors_.push_back(std::move(descriptor));
}

const mrpt::poses::CPose3D& ReferenceDescriptors::pose(std::size_t i) const {
    if (!hasPoses()) throw std::logic_error("ReferenceDescriptors: the references have no poses");
    return poses_.at(i);
}

double ReferenceDescriptors::arcLength(std::size_t i) const {
    if (!hasPoses()) throw std::logic_error("ReferenceDescriptors: the references have no poses");
    return arc_.at(i);
}

const std::vector<double>& ReferenceDescriptors::arcLengths() const {
    if (!hasPoses()) throw std::logic_error("ReferenceDescriptors: the references have no poses");
    return arc_;
}

std::size_t ReferenceDescriptors::nearestInTime(double time_s) const {
    if (times_.empty()) throw std::logic_error("ReferenceDescriptors: empty");
    const auto it = std::lower_bound(times_.begin(), times_.end(), time_s);
    if (it == times_.begin()) return 0;
    if (it == times_.end()) return times_.size() - 1;
    const std::size_t hi = static_cast<std::size_t>(it - times_.begin());
    return (time_s - times_[hi - 1] <= times_[hi] - time_s) ? hi - 1 : hi;
}

std::size_t ReferenceDescriptors::nearestInSpace(const mrpt::poses::CPose3D& p) const {
    if (!hasPoses()) throw std::logic_error("ReferenceDescriptors: the references have no poses");
    std::size_t best = 0;
    double best_d = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < poses_.size(); ++i) {
        const double d = poses_[i].distanceTo(p);
        if (d < best_d) best_d = d, best = i;
    }
    return best;
}

void ReferenceDescriptors::setImageSize(int width, int height) {
    image_width_ = width;
    image_height_ = height;
}

void ReferenceDescriptors::saveDescriptors(const std::string& path) const {
    const std::string tmp = path + ".tmp";
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        if (!out) throw DescriptorFileError(path + ": cannot open for writing");
        out.write(kMagic, sizeof(kMagic));
        put(out, kVersion);
        put<std::int32_t>(out, layout_.thumb_width_px);
        put<std::int32_t>(out, layout_.thumb_height_px);
        put<std::int32_t>(out, layout_.patch_size_px);
        put<std::int32_t>(out, image_width_);
        put<std::int32_t>(out, image_height_);
        put<std::uint64_t>(out, times_.size());
        put<std::uint8_t>(out, hasPoses() ? 1 : 0);
        for (std::size_t i = 0; i < times_.size(); ++i) {
            put(out, times_[i]);
            if (hasPoses()) {
                const auto& p = poses_[i];
                for (double v : {p.x(), p.y(), p.z(), p.yaw(), p.pitch(), p.roll()}) put(out, v);
            }
            out.write(reinterpret_cast<const char*>(descriptors_[i].data()),
                      static_cast<std::streamsize>(descriptors_[i].size()));
        }
        out.flush();
        if (!out) throw DescriptorFileError(path + ": write failed (disk full?)");
    }
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) throw DescriptorFileError(path + ": cannot rename from .tmp: " + ec.message());
}

ReferenceDescriptors ReferenceDescriptors::loadDescriptors(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw DescriptorFileError(path + ": cannot open (missing or unreadable)");
    char magic[8];
    if (!in.read(magic, sizeof(magic)) || std::memcmp(magic, kMagic, sizeof(magic)) != 0) {
        throw DescriptorFileError(path + ": not a coarse descriptor file (bad magic)");
    }
    const auto version = get<std::uint32_t>(in, path, "version");
    if (version != kVersion) {
        throw DescriptorFileError(path + ": unsupported version " + std::to_string(version) +
                                  " (this build reads " + std::to_string(kVersion) + ")");
    }
    CoarseOptions layout;
    layout.thumb_width_px = get<std::int32_t>(in, path, "thumb_width_px");
    layout.thumb_height_px = get<std::int32_t>(in, path, "thumb_height_px");
    layout.patch_size_px = get<std::int32_t>(in, path, "patch_size_px");
    try {
        layout.check();
    } catch (const std::exception& e) {
        throw DescriptorFileError(path + ": bad header: " + e.what());
    }
    const int width = get<std::int32_t>(in, path, "image width");
    const int height = get<std::int32_t>(in, path, "image height");
    const auto count = get<std::uint64_t>(in, path, "frame count");
    const bool has_poses = get<std::uint8_t>(in, path, "pose flag") != 0;
    const std::size_t length =
        static_cast<std::size_t>(layout.thumb_width_px) * layout.thumb_height_px;
    // Refuse absurd counts before allocating: the file must be long enough to hold them.
    const auto here = in.tellg();
    in.seekg(0, std::ios::end);
    const auto remaining = static_cast<std::uint64_t>(in.tellg() - here);
    in.seekg(here);
    const std::uint64_t per_frame = 8 + (has_poses ? 48 : 0) + length;
    if (count > remaining / per_frame) {
        throw DescriptorFileError(path + ": truncated: header says " + std::to_string(count) +
                                  " frames, the file holds " +
                                  std::to_string(remaining / per_frame));
    }
    ReferenceDescriptors refs(layout);
    refs.setImageSize(width, height);
    for (std::uint64_t i = 0; i < count; ++i) {
        const std::string frame = "frame " + std::to_string(i);
        const double t = get<double>(in, path, "time");
        std::optional<mrpt::poses::CPose3D> pose;
        if (has_poses) {
            double v[6];
            for (double& x : v) x = get<double>(in, path, "pose");
            pose = mrpt::poses::CPose3D(v[0], v[1], v[2], v[3], v[4], v[5]);
        }
        Descriptor d(length);
        if (!in.read(reinterpret_cast<char*>(d.data()), static_cast<std::streamsize>(length))) {
            throw DescriptorFileError(path + ": truncated in " + frame);
        }
        try {
            refs.add(t, std::move(d), pose);
        } catch (const std::invalid_argument& e) {
            throw DescriptorFileError(path + ": " + frame + ": " + e.what());
        }
    }
    return refs;
}

ReferenceDescriptors buildReferenceSequence(const std::string& rawlog_path,
                                            const CoarseOptions& options,
                                            const common::PoseTrack* poses, double max_gap_s) {
    options.check();
    ReferenceDescriptors refs(options);
    std::optional<mrpt::poses::CPose3DInterpolator> interpolator;
    if (poses) interpolator = common::makeInterpolator(*poses, max_gap_s);

    CameraFrameStream stream(rawlog_path, options.camera_label, "");
    CameraFrame frame;
    while (stream.next(frame)) {
        std::optional<mrpt::poses::CPose3D> pose;
        if (interpolator) {
            mrpt::poses::CPose3D p;
            bool valid = false;
            interpolator->interpolate(mrpt::Clock::fromDouble(frame.time_s), p, valid);
            if (!valid) {
                throw common::RawlogError(rawlog_path, frame.record,
                                          "no pose at the image time stamp " +
                                              std::to_string(frame.time_s) +
                                              " (outside the pose track or in a gap)");
            }
            pose = p;
        }
        Descriptor d = computeDescriptor(frame.observation->image, options);
        frame.observation->image.unload();
        try {
            refs.add(frame.time_s, std::move(d), pose);
        } catch (const std::invalid_argument& e) {
            throw common::RawlogError(rawlog_path, frame.record, e.what());
        }
    }
    refs.setImageSize(stream.imageWidth(), stream.imageHeight());
    return refs;
}

}  // namespace lookup::coarse
